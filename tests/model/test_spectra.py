"""The spectra fleet (Walker truth), learning gamma with C and m, and the materials table."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from model.binned_damage import bin_cycles, cumulative_at, stretches
from model.fleet import FleetConfig, inspect_at
from model.growth_laws import GROWTH_LAWS
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


@pytest.mark.parametrize(("m", "gamma"), [(3.8, 0.6), (2.5, 0.2), (4.5, 1.0)])
def test_binned_damage_equals_the_sum_over_every_cycle(m: float, gamma: float) -> None:
    """The calibration's binned damage up to each inspection against the exact sum over every
    cycle (model.growth_laws.flight_damage), and its gradient in m and gamma."""
    spectra = generate_spectra_fleet(SpectraFleetConfig(SMALL, gamma=0.6, switch_year=1.5))
    cycles = spectra.cycles.pick(torch.arange(0, 12))
    fpy = SMALL.flights_per_year
    flights = np.array([0, fpy, 2 * fpy, 3 * fpy, fpy // 3, 2 * fpy])
    rows = np.array([0, 0, 0, 5, 7, 11])
    order = np.argsort(rows, kind="stable")
    flights, rows = flights[order], rows[order]
    flight_of, first, ends = stretches(rows, flights, 12, cycles.count.shape[1])
    binned = bin_cycles(cycles, flight_of, int(flight_of.max()) + 1)
    assert len(binned.count) < 0.1 * int((cycles.count > 0).sum())  # it does compress
    m_t = torch.tensor(m, dtype=torch.float64, requires_grad=True)
    g_t = torch.tensor(gamma, dtype=torch.float64, requires_grad=True)
    fast = cumulative_at(
        binned(m_t, g_t, True),
        torch.from_numpy(first),
        torch.from_numpy(ends),
        torch.from_numpy(rows),
    )
    exact_flights = GROWTH_LAWS["walker"].flight_damage(cycles, m_t, g_t)
    cumulative = torch.cat((torch.zeros(12, 1, dtype=torch.float64), exact_flights.cumsum(1)), 1)
    exact = cumulative[torch.from_numpy(rows), torch.from_numpy(flights)]
    assert float(exact[0].detach()) == float(fast[0].detach()) == 0.0  # after 0 flights
    np.testing.assert_allclose(fast.detach().numpy(), exact.detach().numpy(), rtol=1e-4)
    grads = torch.autograd.grad(fast.sum(), (m_t, g_t))
    exact_grads = torch.autograd.grad(exact.sum(), (m_t, g_t))
    for got, want in zip(grads, exact_grads, strict=True):
        assert float(got) == pytest.approx(
            float(want), rel=1e-4, abs=1e-6 * abs(float(exact.sum()))
        )
