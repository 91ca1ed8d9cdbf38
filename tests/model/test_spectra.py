"""The spectra fleet (Walker truth), learning gamma with C and m, and the materials table."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from model.fleet import FleetConfig, inspect_at
from model.hybrid import CrackGrowthModel, ModelSpec
from model.integrate import LoadHistory, Observations
from model.materials import law_for, material, materials
from model.paris_calibration import calibrate_law
from model.physics import ParisLaw
from model.spectra_fleet import (
    CYCLES_PER_FLIGHT,
    SpectraFleetConfig,
    generate_spectra_fleet,
)
from model.tracking import SizingError, TailEvidence

# small and fast-growing (C 5x the thesis's), so that cracks grow to tell laws apart
SMALL = FleetConfig(
    aircraft_per_mix=10, years=3, flights_per_day=2, law=ParisLaw(c=7.5e-11), seed=3
)


def test_spectra_fleet_marches_as_its_truth() -> None:
    """Every flight a GAG cycle and its mission's gusts (R in [-0.3, 0.7]); the model with the
    truth's Walker law on the recorded cycles reproduces the true cracks."""
    spectra = generate_spectra_fleet(SpectraFleetConfig(SMALL, gamma=0.6, switch_year=1.5))
    cycles = spectra.cycles
    assert cycles.stress_range_mpa.shape[2] == CYCLES_PER_FLIGHT
    flown = cycles.count > 0
    ratios = cycles.load_ratio[flown]
    assert float(ratios.min()) >= -0.3 and float(ratios.max()) <= 0.7
    assert set(torch.unique(cycles.count[flown]).tolist()) == {0.5, 1.0}
    model = CrackGrowthModel(ModelSpec(kernel="physics", law=spectra.law, growth_law="walker"))
    with torch.no_grad():
        marched = model.trajectory(spectra.history()).numpy()
    truth = spectra.fleet.crack_length_m
    below = truth < spectra.law.critical_crack_m
    np.testing.assert_allclose(marched[below], truth[below], rtol=1e-9)
    assert float(np.median(truth[:, -1])) > 1.3 * spectra.law.initial_crack_m
    # the load ratios weigh differently by mission: an R-blind range misranks them
    ratio = (spectra.fleet.stress_range_mpa / spectra.paris_equivalent_mpa()) ** spectra.law.m
    by_mission = [float(ratio[spectra.fleet.mission == k].mean()) for k in range(4)]
    assert max(by_mission) / min(by_mission) > 1.2


def test_calibration_learns_walkers_gamma_with_c_and_m() -> None:
    """Started from the thesis's Paris constants (gamma 1, clipped to 0.95 as a start), error-free
    inspections of a fleet whose tails change routes give back the truth's gamma and m; the
    fleet recorded as one R-blind range per flight keeps gamma at 1 and misses the cracks."""
    spectra = generate_spectra_fleet(SpectraFleetConfig(SMALL, gamma=0.6, switch_year=1.5))
    fleet = spectra.fleet
    chosen = np.arange(0, fleet.size, 2)
    fpy = fleet.config.flights_per_year
    sample = inspect_at(fleet, chosen, np.array([fpy, 2 * fpy, 3 * fpy]), noise_sd=0.0)
    obs = sample.observations
    obs = Observations(torch.from_numpy(chosen)[obs.aircraft], obs.flights, obs.crack_length_m)
    history = spectra.history(growth_law="paris")
    evidence = TailEvidence(history, torch.arange(fleet.size), obs, fleet.size)
    law, result = calibrate_law(evidence, ParisLaw(), SizingError(), growth_law="walker")
    assert result.loss_history[-1] < result.loss_history[0]
    assert abs(law.gamma - 0.6) < 0.05
    assert abs(law.m - spectra.law.m) < 0.15
    single = LoadHistory(torch.from_numpy(spectra.paris_equivalent_mpa()), history.lengths)
    blind = TailEvidence(single, torch.arange(fleet.size), obs, fleet.size)
    paris, _ = calibrate_law(blind, ParisLaw(), SizingError(), growth_law="walker")
    assert paris.gamma == 1.0  # no load ratio recorded: nothing to learn it from

    def error(candidate: ParisLaw, loads: LoadHistory) -> float:
        model = CrackGrowthModel(ModelSpec(kernel="physics", law=candidate, growth_law="walker"))
        with torch.no_grad():
            final = model.trajectory(loads)[:, -1].numpy()
        return float(np.median(np.abs(final / fleet.crack_length_m[:, -1] - 1)))

    assert error(law, history) < 0.5 * error(paris, single)


def test_materials_table_cites_its_source_and_sets_the_law() -> None:
    table = materials()
    assert {"2024-T3", "7075-T6", "7075-T651"} <= set(table)
    row = material("2024-T3")
    assert row.citation.startswith("N. E. Dowling")
    assert 1e-12 < row.c < 1e-9 and 2.0 < row.m < 5.0 and 0.0 < row.gamma <= 1.0
    physics = ParisLaw(geometry_factor=1.12, critical_crack_m=0.04)
    law = law_for("7075-T6", physics)
    assert (law.c, law.m, law.gamma) == (table["7075-T6"].c, 3.70, 0.641)
    assert (law.geometry_factor, law.critical_crack_m) == (1.12, 0.04)  # the structure's
    with pytest.raises(ValueError, match="unknown material 'unobtainium'; known: 2024-T3"):
        material("unobtainium")
