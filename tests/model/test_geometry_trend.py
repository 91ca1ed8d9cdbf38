"""The geometry factor's trend read from the measured cracks (model/geometry_trend.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from model.fleet import FleetConfig, generate_fleet, inspect_at, true_geometry_factor
from model.geometry_trend import measured_trend
from model.integrate import LoadHistory, Observations


def _trend(geometry: str, discrepancy: float, *, scatter: float = 0.0, noise: float = 0.0):
    """A 90-tail thesis fleet, 12 tails inspected at year 4 (and year 2 with scatter): the
    measured trend and the truth's equal-life slope beyond the longest measured crack."""
    fleet = generate_fleet(
        FleetConfig(
            aircraft_per_mix=30,
            geometry=geometry,
            discrepancy=discrepancy,
            growth_scatter=scatter,
            seed=1,
        )
    )
    fpy = fleet.config.flights_per_year
    years = np.array([2, 4]) if scatter else np.array([4])
    chosen = np.sort(np.random.default_rng(1).choice(fleet.size, 30 if scatter else 12, False))
    sample = inspect_at(fleet, chosen, years * fpy, noise_sd=noise, seed=1)
    stress = torch.from_numpy(fleet.stress_range_mpa[:, : 4 * fpy]).contiguous()
    loads = LoadHistory(stress, torch.full((fleet.size,), 4 * fpy))
    obs = sample.observations
    observations = Observations(
        torch.from_numpy(chosen)[obs.aircraft], obs.flights, obs.crack_length_m
    )
    law = fleet.config.law
    measured = obs.crack_length_m.double().numpy()
    seen = float(measured[measured < law.critical_crack_m].max())  # a_s
    trend = measured_trend(law, loads, observations, torch.arange(fleet.size), seen)
    assert trend is not None
    # the truth's slope with the same life from a_s to a_crit
    cracks = np.exp(np.linspace(math.log(seen), math.log(law.critical_crack_m), 2048))
    factor = true_geometry_factor(cracks, law, geometry, discrepancy)
    factor = factor / factor[0]

    def life(f: np.ndarray) -> float:
        values = (f * np.sqrt(cracks)) ** (-law.m) * cracks
        return float(np.sum(0.5 * (values[1:] + values[:-1]) * np.diff(np.log(cracks))))

    target = life(factor)
    low, high = -2.0, 3.0
    for _ in range(60):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if life((cracks / cracks[0]) ** mid) > target else (low, mid)
    return trend, 0.5 * (low + high)


def test_exact_inspections_tell_a_finite_widths_rise_from_a_straight_one() -> None:
    """The same cracks over 7-18 mm, told apart by their curvature: the finite width's trend
    beyond them is read steeper than the straight rise's, each near its truth and neither
    past it, with small standard errors (the network's correction read both as ~0.14)."""
    secant, secant_truth = _trend("secant", 0.065)
    linear, linear_truth = _trend("linear", 0.2)
    assert secant.curvature > 0.01 and abs(linear.curvature) < 0.005
    assert secant.slope > 0.15 and secant.slope <= secant_truth
    assert linear.slope == pytest.approx(linear_truth, abs=0.03)
    assert secant.slope_se < 0.05 and linear.slope_se < 0.05


def test_a_flat_factor_reads_no_trend() -> None:
    """A constant factor is the fleet's rate (its level), with no trend beyond the data."""
    flat, _ = _trend("flat", 0.08)
    assert abs(flat.slope) < 0.01 and abs(flat.curvature) < 0.005


def test_scatter_and_sizing_error_leave_the_curvature_unknown() -> None:
    """Tails that scatter, measured with 4 % error: the standard error says the curvature is
    not told, so model.extrapolation keeps the kernel's trend."""
    trend, _ = _trend("secant", 0.065, scatter=0.25, noise=0.04)
    assert trend.slope_se > 0.3
