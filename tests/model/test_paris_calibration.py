"""Learning Paris C and m from inspections (model.paris_calibration)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from model.fleet import FleetConfig, generate_fleet, inspect_at
from model.hybrid import CrackGrowthModel, ModelSpec
from model.integrate import LoadHistory
from model.paris_calibration import calibrate_law, physics_log_crack
from model.physics import ParisLaw
from model.tracking import SizingError, TailEvidence

# another alloy than the thesis's: its own C, m, initial and critical crack
ALLOY = ParisLaw(c=2e-10, m=3.0, initial_crack_m=0.004, critical_crack_m=0.04)


def test_closed_form_matches_the_march_over_variable_loads():
    """The integrated form the calibration fits equals the per-flight march of the physics
    (small growth per flight) up to a_crit, load sequence and growth factor as they come."""
    rng = np.random.default_rng(0)
    stress = torch.from_numpy(rng.uniform(120.0, 220.0, size=(3, 4000)))
    factor = torch.tensor([0.7, 1.0, 1.4], dtype=torch.float64)
    loads = LoadHistory(stress, torch.full((3,), 4000), growth_factor=factor)
    marched = CrackGrowthModel(ModelSpec(kernel="physics", law=ALLOY)).trajectory(loads)
    m = torch.tensor(ALLOY.m, dtype=torch.float64)
    cumulative = torch.cat((torch.zeros(3, 1), (stress**ALLOY.m).cumsum(dim=1)), dim=1)
    log_rate = math.log(ALLOY.c) + ALLOY.m * math.log(math.sqrt(math.pi)) + torch.log(factor)
    closed = physics_log_crack(
        torch.full((3, 1), math.log(ALLOY.initial_crack_m), dtype=torch.float64),
        log_rate[:, None],
        m,
        cumulative,
        ALLOY.held_crack_m,
    ).exp()
    assert float(marched[:, -1].min()) > 2 * ALLOY.initial_crack_m  # the cracks did grow
    below = marched < ALLOY.critical_crack_m  # Paris' law's domain; the march is Euler's
    np.testing.assert_allclose(closed[below].numpy(), marched[below].numpy(), rtol=5e-3)


def _fleet_and_evidence(scatter: float, inspections_per_tail: int, seed: int = 1):
    fleet = generate_fleet(
        FleetConfig(aircraft_per_mix=20, years=4, growth_scatter=scatter, law=ALLOY, seed=seed)
    )
    fpy = fleet.config.flights_per_year
    times = np.arange(1, inspections_per_tail + 1) * (4 * fpy // inspections_per_tail)
    chosen = np.arange(0, fleet.size, 2)
    sample = inspect_at(fleet, chosen, times, noise_sd=0.02, seed=seed)
    obs = sample.observations
    obs = type(obs)(torch.from_numpy(chosen)[obs.aircraft], obs.flights, obs.crack_length_m)
    stress = torch.from_numpy(fleet.stress_range_mpa)
    history = LoadHistory(stress, torch.full((fleet.size,), stress.shape[1]))
    return fleet, TailEvidence(history, torch.arange(fleet.size), obs, fleet.size)


def _evidence(scatter: float, inspections_per_tail: int) -> TailEvidence:
    return _fleet_and_evidence(scatter, inspections_per_tail)[1]


@pytest.mark.parametrize("scatter", [0.0, 0.25])
def test_recovers_another_alloys_constants_from_the_thesis_defaults(scatter):
    """Started from the thesis's C and m (wrong for this alloy), the fit finds the alloy's:
    every tail's crack (inspected or not, at the fleet's rate) from the calibrated physics errs
    within 2 points of the true constants' (the oracle: with scatter, tails differ from any
    fleet rate), the thesis's constants 4 points more or worse; m within what 30 tails can tell."""
    start = ParisLaw(initial_crack_m=ALLOY.initial_crack_m, critical_crack_m=0.04)
    fleet, evidence = _fleet_and_evidence(scatter, 4)
    law, result = calibrate_law(evidence, start, SizingError())
    assert result.loss_history and result.loss_history[-1] < result.loss_history[0]
    assert abs(law.m - ALLOY.m) < 0.1 * ALLOY.m
    error = {}
    for name, candidate in (("thesis", start), ("calibrated", law), ("truth", ALLOY)):
        physics = CrackGrowthModel(ModelSpec(kernel="physics", law=candidate))
        with torch.no_grad():
            final = physics.trajectory(evidence.loads)[:, -1].numpy()
        error[name] = np.median(np.abs(final / fleet.crack_length_m[:, -1] - 1))
    assert error["thesis"] > error["truth"] + 0.04
    assert error["calibrated"] < error["truth"] + 0.02
    assert (law.initial_crack_m, law.critical_crack_m) == (start.initial_crack_m, 0.04)


def test_m_can_be_held():
    law, _ = calibrate_law(_evidence(0.0, 2), ALLOY, SizingError(), learn_m=False)
    assert law.m == ALLOY.m
    assert law.c == pytest.approx(ALLOY.c, rel=0.1)


def test_too_few_inspected_tails_keep_the_law():
    evidence = _evidence(0.0, 2)
    one_tail = evidence.observations.aircraft == evidence.observations.aircraft[0]
    single = TailEvidence(
        evidence.loads, evidence.row_tail, evidence.observations.subset(one_tail), evidence.tails
    )
    law, result = calibrate_law(single, ALLOY, SizingError())
    assert law == ALLOY and not result.loss_history


def test_a_measurement_before_any_flight_says_nothing_of_c_and_m():
    """Every inspected tail also measured at flight 0 (its initial crack, as replicate tests
    record the notch): the same law as without those measurements.  Kept, they made the fit
    overflow and the sizing sd NaN where each tail had one more measurement (alloy-A's refits,
    a traceback from `fleetpinn fit`)."""
    start = ParisLaw(initial_crack_m=ALLOY.initial_crack_m, critical_crack_m=0.04)
    evidence = _evidence(0.25, 2)
    obs = evidence.observations
    rows = torch.unique(obs.aircraft)
    at_start = type(obs)(
        torch.cat((rows, obs.aircraft)),
        torch.cat((torch.zeros_like(rows), obs.flights)),
        torch.cat(
            (
                torch.full((len(rows),), ALLOY.initial_crack_m).to(obs.crack_length_m),
                obs.crack_length_m,
            )
        ),
    )
    with_start = TailEvidence(evidence.loads, evidence.row_tail, at_start, evidence.tails)
    law, _ = calibrate_law(with_start, start, SizingError())
    assert math.isfinite(law.c) and math.isfinite(law.m)
    assert law == calibrate_law(evidence, start, SizingError())[0]
