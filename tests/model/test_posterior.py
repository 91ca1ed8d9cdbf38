"""The door (model/posterior.py): what a stored version holds comes back whole from its model
file, and the predictive methods agree with one another where the cache relies on it."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from model import posterior as door
from model.fleet import FleetConfig, generate_fleet, inspect_at
from model.fleet_spread import SPREAD_PRIOR_SD
from model.forecast import FixedLoads
from model.integrate import LoadHistory, Observations
from model.physics import ParisLaw
from model.tracking_grid import trapezoid_weights

SAMPLES = 40


@pytest.fixture(scope="module")
def fitted() -> tuple[door.Fitted, door.TailEvidence, np.ndarray]:
    """A small fleet that scatters, 8 of 15 tails inspected twice, fitted through the door."""
    fleet = generate_fleet(
        FleetConfig(aircraft_per_mix=5, years=2, growth_scatter=0.2, discrepancy=0.1, seed=3)
    )
    chosen = np.arange(0, 15, 2)
    fpy = fleet.config.flights_per_year
    sample = inspect_at(fleet, chosen, np.array([fpy, 2 * fpy]), noise_sd=0.03, seed=3)
    stress = torch.from_numpy(fleet.stress_range_mpa)
    history = LoadHistory(stress, torch.full((fleet.size,), stress.shape[1]))
    obs = sample.observations
    observations = Observations(
        torch.from_numpy(chosen)[obs.aircraft], obs.flights, obs.crack_length_m
    )
    evidence = door.TailEvidence(history, torch.arange(fleet.size), observations, fleet.size)
    torch.manual_seed(0)
    return door.fit(door.Recipe(law=fleet.config.law), evidence), evidence, chosen


def test_a_model_file_holds_the_whole_posterior(fitted) -> None:
    fit, evidence, _ = fitted
    posterior = fit.posterior
    assert posterior.tracking is not None and posterior.tracking.growth_sd > 0
    metrics = {"tracking": posterior.tracking.to_dict()}
    again = door.LocationPosterior.from_bytes(posterior.to_bytes(metrics))
    assert again.tracking == posterior.tracking
    assert (again.weights is None) == (posterior.weights is None)
    start = evidence.loads.initial_or(posterior.law.initial_crack_m)
    draws = posterior.tail_growth(posterior.update(evidence), SAMPLES, range(evidence.tails))
    mine, theirs = (
        p.crack_now(evidence.loads, start, samples=SAMPLES, seed=5, log_growth=draws.samples)
        for p in (posterior, again)
    )
    assert torch.equal(mine, theirs)


def test_advancing_stored_draws_equals_marching_the_whole_history(fitted) -> None:
    """The cache advances a row's stored draws over new flights (app.services.forecasts.cache_advance):
    the same draws as marching the whole history, up to rounding."""
    fit, evidence, _ = fitted
    posterior = fit.posterior
    loads = evidence.loads
    cut = loads.lengths[0].item() - 30
    early = LoadHistory(
        loads.stress_range_mpa[:, :cut].contiguous(), torch.full_like(loads.lengths, cut)
    )
    start = loads.initial_or(posterior.law.initial_crack_m)
    growth = posterior.tail_growth(posterior.update(evidence), SAMPLES, range(evidence.tails))
    kwargs = {"samples": SAMPLES, "seed": 7, "log_growth": growth.samples}
    whole = posterior.crack_now(loads, start, **kwargs)
    stored = posterior.crack_now(early, start, **kwargs)
    advanced = posterior.advance_samples(
        stored,
        torch.exp(growth.samples),
        loads.stress_range_mpa[:, cut:].contiguous(),
        torch.full((evidence.tails,), 30),
        seed=7,
    )
    assert torch.allclose(advanced, whole, rtol=1e-3)


def test_each_tails_growth_draws_come_from_its_own_seed(fitted) -> None:
    fit, evidence, _ = fitted
    posterior = fit.posterior
    growth = posterior.update(evidence)
    all_tails = posterior.tail_growth(growth, SAMPLES, range(evidence.tails))
    one = posterior.tail_growth(growth.select(torch.tensor([4])), SAMPLES, [4])
    assert torch.equal(all_tails.samples[:, 4], one.samples[:, 0])
    assert torch.allclose(all_tails.point, all_tails.quantiles[:, 1])


def test_the_risk_reads_the_predictive_draws(fitted) -> None:
    """P(critical) is the share of draws at a_crit: near 1 for a tail started past it, 0 for
    one that stays at a0 under no loads."""
    posterior = fitted[0].posterior
    law = posterior.law
    cracks = np.stack([np.full(SAMPLES, 1.2 * law.critical_crack_m), np.full(SAMPLES, 0.005)], 1)
    futures = [FixedLoads(np.full((1, 40), 100.0)), FixedLoads(np.zeros((1, 40)) + 1e-6)]
    risk = posterior.risk(
        cracks,
        futures,
        [4.0, 4.0],
        10,
        samples=SAMPLES,
        seed=0,
        bands=False,
        growth_factor=None,
        marks=[[10], [10]],
        drift_from_m=[np.inf, np.inf],
        tail_seeds=[0, 1],
        detectable_crack_m=None,
    )
    assert risk[0].prob_critical == 1.0 and risk[1].prob_critical == 0.0


def test_the_analysis_is_the_catalogues_physics_alone() -> None:
    law = ParisLaw()
    sizing = door.SizingError(0.07)
    analysis = door.analysis(law, "paris", slope_sd=0.1, growth_sd=0.15, sizing=sizing)
    assert analysis.weights is None and analysis.model.spec.kernel == "physics"
    assert analysis.tracking is not None
    assert analysis.tracking.growth_sd == 0.15 and analysis.tracking.sizing == sizing
    # its tails are drawn from the spread's prior: half-normal, sd 0.3
    z, log_density = analysis.tracking.fleet_grid(401)
    mass = torch.exp(log_density) * trapezoid_weights(z[None, :])[0]
    sd = float((mass / mass.sum() * z**2).sum().sqrt())
    assert sd == pytest.approx(SPREAD_PRIOR_SD, rel=0.05)
    summary = analysis.physics_summary(learned=False)
    assert summary["paris"] == {"c": law.c, "m": law.m, "learned": False}
