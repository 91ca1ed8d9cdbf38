"""The geometry factor's shape as a posterior (model.geometry_posterior): what the measured cracks
tell of it, and what they leave to its prior."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import torch

from model.fleet import FleetConfig, generate_fleet, inspect_at, true_geometry_factor
from model.geometry import GeometryTable
from model.geometry_posterior import ShapePosterior, basis, life_position, shape_posterior
from model.integrate import LoadHistory, Observations
from model.physics import ParisLaw
from model.tracking import SizingError

LAW = ParisLaw()


def _posterior(
    geometry: str,
    discrepancy: float,
    years: tuple[int, ...],
    noise_sd: float = 0.0,
    inspected: int = 30,
) -> tuple[ShapePosterior, float, float]:
    """The shape's posterior on a 90-tail thesis fleet, `inspected` tails measured at `years`
    (sizing error noise_sd, assumed as it is); and the shortest and longest cracks measured below a_crit."""
    fleet = generate_fleet(
        FleetConfig(aircraft_per_mix=30, geometry=geometry, discrepancy=discrepancy, seed=2)
    )
    fpy = fleet.config.flights_per_year
    chosen = np.sort(np.random.default_rng(2).choice(fleet.size, inspected, replace=False))
    times = np.array([y * fpy for y in years])
    sample = inspect_at(fleet, chosen, times, noise_sd=noise_sd, seed=2)
    last = max(years) * fpy
    stress = torch.from_numpy(fleet.stress_range_mpa[:, :last]).contiguous()
    loads = LoadHistory(stress, torch.full((fleet.size,), last))
    obs = sample.observations
    observations = Observations(
        torch.from_numpy(chosen)[obs.aircraft], obs.flights, obs.crack_length_m
    )
    sizing = SizingError(relative_sd=max(noise_sd, 1e-3), absolute_sd_m=0.0)
    posterior = shape_posterior(
        LAW, loads, observations, torch.arange(fleet.size), sizing, 0.0, 0.1
    )
    below = obs.crack_length_m[obs.crack_length_m < LAW.critical_crack_m]
    return posterior, float(below.min()), float(below.max())


def _rise(shape: ShapePosterior, low_m: float, high_m: float) -> tuple[float, float]:
    """g(high) - g(low): its posterior mean and sd."""
    ends = basis(life_position(LAW, np.array([low_m, high_m])))
    row = ends[1:] - ends[:1]
    return float((row @ np.asarray(shape.mean))[0]), float(shape.rise_sd(row)[0])


# an accuracy study (150-190 s each on a 2-core machine under the suite: five rounds of 90 tails
# through the shape's Laplace fit): `make test-all`
@pytest.mark.slow
@pytest.mark.parametrize(("geometry", "discrepancy"), [("linear", 0.25), ("secant", 0.08)])
def test_exact_inspections_over_the_life_tell_the_factors_rise(
    geometry: str, discrepancy: float
) -> None:
    """Inspected at years 1 to 5, exactly: the posterior's rise of ln F over the measured cracks
    is the truth's within 15 % (the prior's smoothness holds a secant's steepest part back a
    little) and two sds, and much narrower than the prior's."""
    shape, low, top = _posterior(geometry, discrepancy, (1, 2, 3, 4, 5))
    truth = true_geometry_factor(np.array([low, top]), LAW, geometry, discrepancy)
    mean, sd = _rise(shape, low, top)
    _, prior_sd = _rise(ShapePosterior.prior(LAW, 0.1), low, top)
    rise = math.log(truth[1] / truth[0])
    assert abs(mean - rise) < 0.15 * rise + 2 * sd
    assert sd < 0.3 * prior_sd


def test_a_flat_factor_reads_no_rise() -> None:
    """A constant factor the law misses is the fleet's rate: no shape."""
    shape, low, top = _posterior("flat", 0.08, (2, 4))
    mean, sd = _rise(shape, low, top)
    assert abs(mean) < 2 * sd + 0.01


def test_beyond_the_measured_cracks_the_prior_returns() -> None:
    """Inspected once at year 2, the posterior pins the shape over the measured cracks, and past
    them its spread grows back towards the prior's: the rise from a_s to a_crit is less known
    than the one over the measured cracks."""
    shape, low, top = _posterior("linear", 0.1, (2,), noise_sd=0.02)
    _, within = _rise(shape, low, top)
    _, beyond = _rise(shape, top, LAW.critical_crack_m)
    _, prior_beyond = _rise(ShapePosterior.prior(LAW, 0.1), top, LAW.critical_crack_m)
    assert beyond > 2 * within
    assert 0.3 * prior_beyond < beyond <= prior_beyond * (1 + 1e-9)


def test_sizing_error_leaves_the_shape_less_told() -> None:
    exact, _, top = _posterior("linear", 0.1, (2, 4))
    noisy, _, _ = _posterior("linear", 0.1, (2, 4), noise_sd=0.08)
    assert _rise(noisy, top, LAW.critical_crack_m)[1] > _rise(exact, top, LAW.critical_crack_m)[1]


def test_the_corrected_law_carries_the_mean_shape_up_to_the_measured_cracks_and_holds_it() -> None:
    """The physics with its learned correction inside: F exp(g) at the posterior mean up to a_s,
    held beyond it (where the forecast's draws take over), a0's factor unchanged."""
    slopes = np.linspace(0.1, 0.5, len(ShapePosterior.prior(LAW, 0.1).mean))
    shape = ShapePosterior.of(slopes, np.asarray(ShapePosterior.prior(LAW, 0.1).covariance))
    seen = 0.02
    law = shape.corrected_law(replace(LAW, geometry_factor=1.1), seen)
    table = law.geometry_table
    assert table is not None and table.crack_length_m[0] == LAW.initial_crack_m
    cracks = np.array([LAW.initial_crack_m, 0.01, seen, 0.04])
    expected = 1.1 * np.exp(basis(life_position(LAW, np.minimum(cracks, seen))) @ slopes)
    got = table.at(torch.from_numpy(cracks)).numpy()
    np.testing.assert_allclose(got, expected, rtol=2e-3)
    assert got[0] == pytest.approx(1.1) and got[-1] == got[-2]


def test_a_tables_own_rise_goes_on_beyond_the_measured_cracks() -> None:
    edge = GeometryTable((0.005, 0.03, 0.05), (1.0, 1.1, 1.5))
    law = replace(LAW, geometry_table=edge)
    shape = ShapePosterior.of(np.full(len(ShapePosterior.prior(law, 0.1).mean), 0.2), np.eye(9))
    corrected = shape.corrected_law(law, 0.02).geometry_table
    assert corrected is not None
    beyond = torch.tensor([0.03, 0.04, 0.05], dtype=torch.float64)
    ratio = corrected.at(beyond) / edge.at(beyond)
    torch.testing.assert_close(ratio, ratio[:1].expand(3))  # the correction held, the table's rise
    assert float(ratio[0]) == pytest.approx(
        math.exp(0.2 * float(life_position(law, 0.02))), rel=1e-3
    )
    assert shape.corrected_law(law, LAW.initial_crack_m) is law  # nothing measured: unchanged
