"""The extrapolation beyond the measured cracks (model.extrapolation), and what it does to a
fleet whose geometry factor accelerates, or stays flat, where nobody measured."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from model.extrapolation import Extrapolation, fitted_extrapolation
from model.fleet import FleetConfig, generate_fleet, inspect_at
from model.forecast import FixedLoads
from model.geometry import GeometryTable
from model.geometry_posterior import KNOTS, ShapePosterior, life_position, per_log_crack
from model.integrate import LoadHistory, Observations
from model.kernel_choice import Recipe
from model.physics import ParisLaw
from model.prognosis import probabilistic_forecast
from model.tracking import SizingError, TailEvidence

LAW = ParisLaw()
LIFE = math.log(LAW.critical_crack_m / LAW.initial_crack_m)
# F rising towards an edge, past the measured cracks (0.02 m) up to a_crit and held after it
EDGE = GeometryTable((0.005, 0.02, 0.035, 0.05), (1.0, 1.05, 1.2, 1.5))
WIDE = ShapePosterior.prior(LAW, 0.1)


def _g(a: float, slopes: np.ndarray) -> float:
    """g at crack a: the integral of the slope, linear between the knots (a fine trapezoid)."""
    x = float(life_position(LAW, a))
    xs = np.linspace(0.0, x, 2001)
    slope = np.interp(xs, np.linspace(0, 1, KNOTS + 1), slopes)
    return float(np.sum(0.5 * (slope[1:] + slope[:-1]) * np.diff(xs)))


def _march(
    shape: np.ndarray,
    seen_m: float,
    flights: int = 8000,
    stress_mpa: float = 110.0,
    table: GeometryTable | None = None,
    substeps: int = 1,
) -> np.ndarray:
    """Euler, `substeps` steps per flight, with the geometry factor (times the table's F(a))
    exp(g(x) - g(x_s)) past seen_m; the crack after each flight."""
    a = np.empty(flights + 1)
    a[0] = 0.01
    for t in range(flights):
        crack = a[t]
        for _ in range(substeps):
            factor = math.exp(_g(max(crack, seen_m), shape) - _g(seen_m, shape))
            if table is not None:
                factor *= np.interp(crack, table.crack_length_m, table.factor)
            step = LAW.c * (factor * stress_mpa * math.sqrt(math.pi * crack)) ** LAW.m
            crack = min(crack + step / substeps, LAW.held_crack_m)
        a[t + 1] = crack
    return a


SHAPES = {
    "falling": np.full(KNOTS + 1, -0.2),
    "accelerating": np.linspace(0.0, 0.8, KNOTS + 1),
    "rise then fall": np.concatenate([np.full(5, 0.3), np.full(KNOTS - 4, -0.3)]),
}


@pytest.mark.parametrize("name", list(SHAPES))
@pytest.mark.parametrize("table", [None, EDGE])
def test_mapping_equals_the_march_under_the_shape_and_inverts(
    name: str, table: GeometryTable | None
) -> None:
    """Past a_s the map is the march under F exp(g(x) - g(x_s)) (a table's F times it), unchanged
    before a_s, and `within` undoes it."""
    seen = 0.02
    law = ParisLaw(geometry_table=table)
    extrapolation = Extrapolation.under(law, seen, WIDE)
    # the map is the continuous march: Euler at ten steps a flight is within 0.3 % of it
    shape, flights = SHAPES[name], 6000 if table else 9000
    plain = np.zeros(KNOTS + 1)
    base = torch.from_numpy(_march(plain, seen, flights, table=table, substeps=4))[None, :]
    mapped = extrapolation.beyond(base, torch.from_numpy(shape)[None, :])[0].numpy()
    truth = _march(shape, seen, flights, table=table, substeps=4)
    below = (truth < 0.05) & (base[0].numpy() < 0.05)  # steps small against the crack
    assert below.sum() > 100 and truth[below].max() > 0.035
    np.testing.assert_allclose(mapped[below], truth[below], rtol=4e-3)
    early = base[0].numpy() <= seen
    assert np.all(mapped[early] == base[0].numpy()[early])
    back = extrapolation.within(torch.from_numpy(mapped)[None, :], torch.from_numpy(shape)[None])
    finite = mapped < LAW.held_crack_m
    np.testing.assert_allclose(back[0].numpy()[finite], base[0].numpy()[finite], rtol=1e-6)


def test_a_crack_maps_alike_whatever_its_batch() -> None:
    """A tail's forecast must not depend on the tails beside it: one sample's cracks map the
    same alone and among others."""
    extrapolation = Extrapolation.under(LAW, 0.02, WIDE)
    cracks = torch.tensor([[0.021, 0.03, 0.045], [0.025, 0.01, 0.04]], dtype=torch.float64)
    shapes = torch.from_numpy(np.stack([SHAPES["falling"], SHAPES["accelerating"]]))
    both = extrapolation.beyond(cracks, shapes)
    alone = extrapolation.beyond(cracks[1:], shapes[1:])
    assert torch.equal(both[1:], alone)


def test_a_file_before_the_shape_maps_as_its_power_of_a() -> None:
    """A model file written with eta ~ N(slope, slope_sd**2), F scaled by (a / a_s)**eta beyond
    a_s, reads as the shape whose slope is eta d ln a / dx at each knot: the same map, but for
    the slope's linear pieces between knots where eta ln a's is 1 / a (within 2 %)."""
    seen, eta = 0.02, 0.15
    old = Extrapolation.from_dict({"seen_crack_m": seen, "slope": eta, "slope_sd": 0.1}, LAW)
    assert old.shape.mean == pytest.approx(tuple(eta * per_log_crack(LAW)))
    cracks = torch.tensor([[0.021, 0.03, 0.045]], dtype=torch.float64)
    mapped = old.beyond(cracks, torch.from_numpy(old.shape.mean[None, :]))
    q, p = 1 - LAW.m / 2, 1 - LAW.m / 2 - LAW.m * eta  # the closed form under (a / a_s)**eta
    damage = (cracks**q - seen**q) / q
    expected = (seen**p + p * damage * seen ** (-LAW.m * eta)) ** (1 / p)
    torch.testing.assert_close(mapped, expected, rtol=2e-2, atol=0)
    again = Extrapolation.from_dict(old.to_dict(), LAW)
    assert again == old


def test_draws_are_the_posterior_s_quantiles() -> None:
    prior = np.asarray(WIDE.covariance)
    shape = ShapePosterior.of(np.linspace(-0.1, 0.2, KNOTS + 1), prior)
    draws = Extrapolation.under(LAW, 0.02, shape).draws(1024, seed=3)
    assert draws.shape == (1024, KNOTS + 1)
    np.testing.assert_allclose(draws.mean(dim=0).numpy(), shape.mean, atol=0.01)
    np.testing.assert_allclose(np.cov(draws.numpy().T), prior, rtol=0.1, atol=0.1 * prior.max())


def test_the_extrapolation_starts_after_the_longest_crack_measured_below_critical() -> None:
    """One tail measured past a_crit (it failed) says nothing of the shape between the other
    tails' cracks and a_crit: a_s is the longest crack measured below a_crit, and the law's
    table is the map's."""
    law = ParisLaw(geometry_table=EDGE)
    measured = torch.tensor([0.008, 0.018, 1.2 * LAW.critical_crack_m], dtype=torch.float64)
    observations = Observations(torch.tensor([0, 0, 1]), torch.tensor([10, 30, 50]), measured)
    stress = torch.linspace(90.0, 130.0, 50, dtype=torch.float64).expand(2, -1)
    loads = LoadHistory(stress.contiguous(), torch.tensor([50, 50]))
    extrapolation = fitted_extrapolation(law, observations, loads, SizingError(), 0.1, 0.1)
    assert extrapolation.seen_crack_m == 0.018 and extrapolation.geometry == EDGE


def test_no_crack_measured_leaves_the_prior() -> None:
    observations = Observations(  # a non-detection
        torch.tensor([0]),
        torch.tensor([40]),
        torch.tensor([0.0], dtype=torch.float64),
        detected=torch.tensor([False]),
        detection_a50_m=torch.tensor([0.002], dtype=torch.float64),
    )
    loads = LoadHistory(torch.full((1, 50), 100.0, dtype=torch.float64), torch.tensor([50]))
    extrapolation = fitted_extrapolation(LAW, observations, loads, SizingError(), 0.1, 0.1)
    assert extrapolation.seen_crack_m == LAW.initial_crack_m
    assert extrapolation.shape == ShapePosterior.prior(LAW, 0.1)


def _forecast_fleet(geometry: str, discrepancy: float, seed: int = 1):
    """A 90-tail thesis fleet, 12 tails inspected exactly at year 4, every tail's year-5
    crack forecast from year 4 with the true loads: (forecast, truth, inspected, seen)."""
    fleet = generate_fleet(
        FleetConfig(aircraft_per_mix=30, geometry=geometry, discrepancy=discrepancy, seed=seed)
    )
    fpy = fleet.config.flights_per_year
    year4 = 4 * fpy
    chosen = np.sort(np.random.default_rng(seed).choice(fleet.size, 12, replace=False))
    sample = inspect_at(fleet, chosen, np.array([year4]))
    stress = torch.from_numpy(fleet.stress_range_mpa)
    history = LoadHistory(stress[:, :year4].contiguous(), torch.full((fleet.size,), year4))
    obs = sample.observations
    observations = Observations(
        torch.from_numpy(chosen)[obs.aircraft], obs.flights, obs.crack_length_m
    )
    evidence = TailEvidence(history, torch.arange(fleet.size), observations, fleet.size)
    torch.manual_seed(seed)
    fitted, tracked = Recipe(law=fleet.config.law, sizing=SizingError()).fit(evidence)
    forecast = probabilistic_forecast(
        fitted.model,
        fitted.weights,
        FixedLoads(fleet.stress_range_mpa[:, year4:]),
        history=history,
        samples=100,
        report_flights=torch.tensor([0, fleet.stress_range_mpa.shape[1] - year4]),
        growth_factor=torch.exp(tracked.posterior.sample(100, seed=seed)),
    )
    inspected = np.zeros(fleet.size, dtype=bool)
    inspected[chosen] = True
    return forecast, fleet.crack_length_m[:, -1], inspected, float(obs.crack_length_m.max())


@pytest.mark.xfail(
    strict=True,
    reason="issue 39, open: a factor accelerating five prior sds beyond every measured crack "
    "(exact inspections, secant W = 1.3 a_crit) is outside the shape's prior; 1-2 of 8 flagged",
)
def test_an_accelerating_geometry_factor_beyond_the_measured_cracks_is_flagged() -> None:
    """Measured cracks stop near 0.4 a_crit; the truth's secant factor accelerates past them.
    Measured: 18 of 25 tails that reach a_crit flagged on the 300-tail fleet
    (benchmarks/extrapolation.py); with the correction only held at the box's edge, 0 of 28."""
    forecast, truth, _, seen = _forecast_fleet("secant", 0.065)
    assert seen < 0.45 * LAW.critical_crack_m
    reach = truth >= LAW.critical_crack_m
    assert reach.sum() >= 5
    prob = forecast.prob_critical.numpy()
    assert (prob[reach] >= 0.5).mean() >= 0.6
    assert ((prob >= 0.5) & ~reach).sum() <= 2
    beyond = (truth > seen) & ~reach
    assert (truth[beyond] <= forecast.crack_p95_m[beyond, 1].numpy()).mean() >= 0.85


def test_a_flat_discrepancy_is_the_fleet_s_rate_and_uninspected_tails_inherit_it() -> None:
    """A constant geometry factor of 1.08 the physics lacks: uninspected tails' year-5 cracks
    unbiased (measured median error 0.05 %) with bands not wider than needed (median
    [p05, p95] width ~5 %); before the fleet mean they were 27 % short."""
    forecast, truth, inspected, _ = _forecast_fleet("flat", 0.08)
    below = ~inspected & (truth < LAW.critical_crack_m)
    p50 = forecast.crack_p50_m[:, 1].numpy()
    error = p50[below] / truth[below] - 1
    assert abs(float(np.median(error))) < 0.015
    p05, p95 = forecast.crack_p05_m[:, 1].numpy(), forecast.crack_p95_m[:, 1].numpy()
    assert float(np.median((p95 - p05)[below] / p50[below])) < 0.10
    assert ((p05 <= truth) & (truth <= p95))[below].mean() >= 0.85
