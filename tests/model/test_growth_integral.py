"""The separable growth integral H (model.growth_integral) and the calibration of C and m
that reads a geometry table through it, so that the table is counted once."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import torch

from model.fleet import FleetConfig, generate_fleet, inspect_at, true_geometry_factor
from model.geometry import GeometryTable
from model.growth_integral import log_integral_grid, table_log_crack
from model.hybrid import CrackGrowthModel, ModelSpec
from model.integrate import LoadHistory
from model.paris_calibration import calibrate_law, physics_log_crack
from model.physics import ParisLaw
from model.tracking import SizingError, TailEvidence

ALLOY = ParisLaw(c=2e-10, m=3.0, initial_crack_m=0.004, critical_crack_m=0.04)
# a centre-cracked panel of half width b: F = sqrt(sec(pi a / 2b)) rises 1.003 -> 1.39 from
# a0 to a_crit (the replicate panels of issue 41)
HALF_WIDTH_M = 0.0612


def _secant_table() -> GeometryTable:
    """The truth's F(a) as a table, to where the truth holds it (0.98 b)."""
    a = np.geomspace(ALLOY.initial_crack_m, 0.98 * HALF_WIDTH_M, 64)
    factor = true_geometry_factor(a, ALLOY, "secant", HALF_WIDTH_M)
    return GeometryTable.of(a.tolist(), factor.tolist())


def test_a_constant_table_gives_the_closed_form() -> None:
    m = torch.tensor(3.4, dtype=torch.float64)
    flat = GeometryTable((0.001, 1.0), (1.2, 1.2))
    grid = log_integral_grid(flat, m, 0.002, 0.5)
    log_a0 = torch.full((5,), math.log(0.003), dtype=torch.float64)
    damage = torch.tensor([0.0, 1e8, 1e9, 3e9, 1e12], dtype=torch.float64)
    log_c = math.log(1e-11)
    got = table_log_crack(log_a0, torch.full_like(log_a0, log_c), damage, grid)
    log_rate = log_c + 3.4 * math.log(1.2 * math.sqrt(math.pi))
    want = physics_log_crack(log_a0, torch.full_like(log_a0, log_rate), m, damage, 0.5)
    assert torch.allclose(got.exp(), want.exp(), rtol=1e-5)
    assert float(got[-1].exp()) == pytest.approx(0.5, rel=1e-8)  # ran away: held


def test_the_integral_matches_the_march_with_a_rising_table() -> None:
    """The per-flight march of the physics with the table, against H's inversion."""
    table = _secant_table()
    law = replace(
        ALLOY, geometry_factor=table.value_at(ALLOY.initial_crack_m), geometry_table=table
    )
    rng = np.random.default_rng(0)
    stress = torch.from_numpy(rng.uniform(100.0, 160.0, size=(3, 30000)))
    loads = LoadHistory(stress, torch.full((3,), 30000))
    marched = CrackGrowthModel(ModelSpec(kernel="physics", law=law)).trajectory(loads)
    m = torch.tensor(ALLOY.m, dtype=torch.float64)
    grid = log_integral_grid(table, m, 0.999 * ALLOY.initial_crack_m, law.held_crack_m)
    damage = torch.cat((torch.zeros(3, 1), (stress**ALLOY.m).cumsum(dim=1)), dim=1)
    log_a0 = torch.full((3, 1), math.log(ALLOY.initial_crack_m), dtype=torch.float64)
    log_rate = torch.full((3, 1), math.log(ALLOY.c), dtype=torch.float64)
    closed = table_log_crack(log_a0, log_rate, damage, grid).exp()
    below = marched < ALLOY.critical_crack_m
    assert float(marched[below].max()) > 0.03  # it reached the table's steep part
    np.testing.assert_allclose(closed[below].numpy(), marched[below].numpy(), rtol=5e-3)


def _finite_width_evidence() -> tuple[np.ndarray, TailEvidence]:
    fleet = generate_fleet(
        FleetConfig(aircraft_per_mix=20, years=4, law=ALLOY, geometry="secant",
                    discrepancy=HALF_WIDTH_M, growth_scatter=0.1, seed=3)
    )  # fmt: skip
    fpy = fleet.config.flights_per_year
    chosen = np.arange(0, fleet.size, 2)
    sample = inspect_at(fleet, chosen, np.arange(1, 5) * fpy, noise_sd=0.02, seed=3)
    obs = sample.observations
    obs = type(obs)(torch.from_numpy(chosen)[obs.aircraft], obs.flights, obs.crack_length_m)
    stress = torch.from_numpy(fleet.stress_range_mpa)
    history = LoadHistory(stress, torch.full((fleet.size,), stress.shape[1]))
    return fleet.crack_length_m, TailEvidence(history, torch.arange(fleet.size), obs, fleet.size)


def test_calibration_with_the_true_table_recovers_c_and_m() -> None:
    """A finite-width fleet (F 1.003 -> 1.39): started from the thesis's C and m, the fit with
    the true table entered finds the alloy's m and C; with F = 1 it bends m to absorb the
    rise.  Each law's march then forecasts every tail's crack up to a_crit; the table's is no
    worse than F = 1's."""
    truth, evidence = _finite_width_evidence()
    table = _secant_table()
    start = ParisLaw(initial_crack_m=ALLOY.initial_crack_m, critical_crack_m=ALLOY.critical_crack_m)
    with_table = replace(
        start, geometry_factor=table.value_at(start.initial_crack_m), geometry_table=table
    )
    fitted_table, _ = calibrate_law(evidence, with_table, SizingError())
    fitted_flat, _ = calibrate_law(evidence, start, SizingError())
    assert abs(fitted_table.m - ALLOY.m) < 0.05 * ALLOY.m
    assert abs(math.log(fitted_table.c / ALLOY.c)) < 0.3
    assert abs(fitted_table.m - ALLOY.m) <= abs(fitted_flat.m - ALLOY.m)
    # what the calibration did before: C and m fitted with F held at F(a0), then marched with
    # the table, which counted its rise twice
    twice = replace(fitted_flat, geometry_factor=with_table.geometry_factor, geometry_table=table)
    errors = {}
    below = truth < ALLOY.critical_crack_m
    for name, law in (("table", fitted_table), ("flat", fitted_flat), ("twice", twice)):
        with torch.no_grad():
            marched = CrackGrowthModel(ModelSpec(kernel="physics", law=law)).trajectory(
                evidence.loads
            )
        errors[name] = float(np.median(np.abs(marched.numpy()[below] / truth[below] - 1)))
    print(fitted_table.c, fitted_table.m, fitted_flat.c, fitted_flat.m, errors)
    assert errors["table"] <= min(errors["flat"], errors["twice"])
