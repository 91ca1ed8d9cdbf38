"""Individual aircraft tracking: per-tail growth posteriors against a dense grid oracle."""

import math
from dataclasses import replace

import numpy as np
import pytest
import torch

from model.fleet import DISCREPANCY_20PCT as DISCREPANCY
from model.fleet import FleetConfig, generate_fleet, inspect_at
from model.fleet_spread import estimate_growth_prior
from model.hybrid import CrackGrowthModel, ModelSpec, default_box
from model.integrate import LoadHistory, Observations
from model.physics import ParisLaw, paris_closed_form
from model.tracking import GrowthPosterior, SizingError, TailEvidence, TrackingPrior
from model.tracking_fit import InspectedTails, fit_prior, fit_tracked
from model.tracking_grid import growth_posterior
from model.train import build_crack_model, fit_crack_model

LAW = ParisLaw(c=6e-11)


def _constant_load_evidence(measured: list[float], flights: list[int]) -> TailEvidence:
    loads = LoadHistory(torch.full((1, 3000), 100.0, dtype=torch.float64), torch.tensor([3000]))
    obs = Observations(
        torch.zeros(len(flights), dtype=torch.long),
        torch.tensor(flights),
        torch.tensor(measured, dtype=torch.float64),
    )
    return TailEvidence(loads, torch.tensor([0]), obs, 1)


def test_posterior_matches_a_dense_grid_oracle_from_the_closed_form() -> None:
    """Paris' closed form with C e^z: the posterior on a 20,001-point grid is the oracle."""
    model = CrackGrowthModel(ModelSpec(kernel="physics", law=LAW))
    flights = [1000, 2500]

    def closed_form(z: torch.Tensor, n: int) -> torch.Tensor:
        # C e^z over n flights = C over n e^z flights; Euler per flight is within ~1e-4 of it
        return paris_closed_form(LAW.initial_crack_m, 100.0, n * torch.exp(z), LAW)

    measured = [
        float(closed_form(torch.tensor(0.2), n)) * e
        for n, e in zip(flights, (1.03, 0.98), strict=True)
    ]
    evidence = _constant_load_evidence(measured, flights)
    prior = TrackingPrior(0.3, SizingError(0.04, 0.0002))
    posterior = growth_posterior(model, evidence, prior)

    z = torch.linspace(-2, 2, 20_001, dtype=torch.float64)
    log_post = -0.5 * (z / prior.growth_sd) ** 2
    for n, y in zip(flights, measured, strict=True):
        pred = closed_form(z, n)
        sd = prior.sizing.log_sd(pred)
        log_post = log_post - 0.5 * ((math.log(y) - torch.log(pred)) / sd) ** 2 - torch.log(sd)
    log_post = torch.nan_to_num(log_post, nan=-math.inf)  # past the closed form's divergence
    w = torch.exp(log_post - log_post.max())
    cdf = torch.cumsum(w, 0) / w.sum()
    oracle = [
        float(z[int(torch.searchsorted(cdf, torch.tensor(q).double()))]) for q in (0.05, 0.5, 0.95)
    ]
    got = posterior.quantiles([0.05, 0.5, 0.95])[0].tolist()
    assert got == pytest.approx(oracle, abs=0.005)
    assert got[2] - got[0] < 0.3  # the inspections narrow the prior's 0.99-wide band


def test_fleet_prior_learns_scatter_and_sizing_error_and_shrinks_without_scatter() -> None:
    fleet_cfg = dict(aircraft_per_mix=20, years=4, seed=3)
    fpy = FleetConfig(**fleet_cfg).flights_per_year
    model = CrackGrowthModel(ModelSpec(kernel="physics"))
    results = {}
    for scatter in (0.0, 0.25):
        fleet = generate_fleet(FleetConfig(**fleet_cfg, growth_scatter=scatter))
        chosen = np.arange(0, fleet.size, 1)
        sample = inspect_at(fleet, chosen, np.array([2 * fpy, 4 * fpy]), noise_sd=0.04, seed=1)
        evidence = TailEvidence(
            sample.loads, torch.arange(len(chosen)), sample.observations, len(chosen)
        )
        prior, _ = fit_prior(model, evidence, SizingError(0.1, 0.0))
        results[scatter] = prior
        truth = fleet.crack_length_m[chosen][
            sample.observations.aircraft, sample.observations.flights
        ]
        realised = np.log(sample.observations.crack_length_m.numpy() / truth).std()
        assert prior.sizing.relative_sd == pytest.approx(realised, abs=0.006)
    assert results[0.0].growth_sd < 0.03
    assert results[0.25].growth_sd == pytest.approx(0.25, abs=0.07)


def test_uninspected_tails_keep_the_prior_and_an_inspection_moves_only_its_tail() -> None:
    model = CrackGrowthModel(ModelSpec(kernel="physics", law=LAW))
    loads = LoadHistory(torch.full((3, 300), 100.0, dtype=torch.float64), torch.tensor([300] * 3))
    prior = TrackingPrior(0.25, SizingError(0.04, 0.0))
    expected_crack = float(model.final_crack(loads)[0])

    def posterior(measured: float) -> GrowthPosterior:
        obs = Observations(torch.tensor([1]), torch.tensor([300]), torch.tensor([measured]))
        return growth_posterior(model, TailEvidence(loads, torch.arange(3), obs, 3), prior)

    low, high = posterior(expected_crack * 0.8), posterior(expected_crack * 1.2)
    q_low, q_high = low.quantiles([0.05, 0.5, 0.95]), high.quantiles([0.05, 0.5, 0.95])
    for tail in (0, 2):
        assert torch.allclose(q_low[tail], q_high[tail])
        assert q_low[tail].tolist() == pytest.approx([-1.645 * 0.25, 0.0, 1.645 * 0.25], abs=0.01)
    assert float(q_low[1, 1]) < -0.05 < 0.05 < float(q_high[1, 1])
    samples = high.sample(400, seed=0)
    assert samples.shape == (400, 3)
    assert float(samples[:, 0].std()) == pytest.approx(0.25, rel=0.05)


def test_the_fleet_s_own_rate_is_the_prior_s_mean_and_uninspected_tails_inherit_it() -> None:
    """Eight tails growing 1.5x the physics' rate (a constant it lacks) and barely scattering:
    the fleet prior's mean carries the 1.5, not a spread, and a tail never inspected gets it."""
    model = CrackGrowthModel(ModelSpec(kernel="physics", law=LAW))
    tails = 9
    loads = LoadHistory(
        torch.full((tails, 3000), 100.0, dtype=torch.float64), torch.tensor([3000] * tails)
    )
    z = np.log(1.5) + np.random.default_rng(4).normal(0.0, 0.02, tails - 1)
    truth = replace(
        loads.select(torch.arange(tails - 1)), growth_factor=torch.from_numpy(np.exp(z))
    )
    measured = model.final_crack(truth)
    obs = Observations(torch.arange(tails - 1), torch.full((tails - 1,), 3000), measured)
    evidence = TailEvidence(loads, torch.arange(tails), obs, tails)
    prior, _ = fit_prior(model, evidence, SizingError(0.01, 0.0), estimate_sizing=False)
    assert prior.growth_mean == pytest.approx(math.log(1.5), abs=0.03)
    assert prior.growth_sd < 0.05
    uninspected = growth_posterior(model, evidence, prior).quantiles([0.5])[tails - 1, 0]
    assert float(uninspected) == pytest.approx(math.log(1.5), abs=0.03)


def test_a_surprising_measurement_moves_its_tail_in_a_fleet_that_does_not_scatter() -> None:
    """The fleet's learned spread ~0 (the demo's 2.7e-9): a measurement 1.8x the forecast (12
    sizing sds) moves its tail's factor until its crack is near the measurement, and its band
    widens; an unsurprising one leaves the tail at the fleet's rate."""
    model = CrackGrowthModel(ModelSpec(kernel="physics", law=LAW))
    loads = LoadHistory(torch.full((2, 3000), 100.0, dtype=torch.float64), torch.tensor([3000] * 2))
    prior = TrackingPrior(2.7e-9, SizingError(0.05, 0.0))
    forecast = float(model.final_crack(loads)[0])
    obs = Observations(
        torch.tensor([0, 1]),
        torch.tensor([3000, 3000]),
        torch.tensor([forecast * 1.01, forecast * 1.8]),
    )
    posterior = growth_posterior(model, TailEvidence(loads, torch.arange(2), obs, 2), prior)
    median = torch.exp(posterior.quantiles([0.5])[:, 0])
    moved = replace(loads, growth_factor=median)
    crack = model.final_crack(moved)
    assert float(median[0]) == pytest.approx(1.0, abs=0.02)
    assert float(crack[1]) == pytest.approx(forecast * 1.8, rel=0.1)
    spread = posterior.quantiles([0.05, 0.95])
    assert float(spread[1, 1] - spread[1, 0]) > 1.5 * float(spread[0, 1] - spread[0, 0])


@pytest.mark.slow
def test_joint_fit_keeps_scatter_out_of_the_kernel_and_the_kernel_out_of_the_factors() -> None:
    """A residual model fitted with every tail at the fleet rate reads scatter as physics; the
    joint fit of weights and tail factors from the physics (fit_tracked) recovers each tail's
    own factor far better than the factors read off that shared fit afterwards (rounds=0), and the fleet
    spread (against the realised spread of these 45 tails) and the sizing error with it."""
    fleet = generate_fleet(
        FleetConfig(
            aircraft_per_mix=15, years=4, seed=5, growth_scatter=0.25, discrepancy=DISCREPANCY
        )
    )
    fpy = fleet.config.flights_per_year
    everyone = np.arange(fleet.size)
    sample = inspect_at(fleet, everyone, np.array([2 * fpy, 4 * fpy]), noise_sd=0.04, seed=2)
    evidence = TailEvidence(sample.loads, torch.arange(fleet.size), sample.observations, fleet.size)
    truth = np.log(fleet.growth_factor)
    errors, priors = {}, {}
    shared, _ = fit_crack_model(sample.loads, sample.observations)
    fitted = fit_tracked(shared, evidence, SizingError(), rounds=0)  # factors read afterwards
    priors[0], errors[0] = fitted.prior, _rms(fitted.posterior.mean().numpy() - truth)
    fitted = fit_tracked(build_crack_model(sample.loads), evidence, SizingError())
    priors[1], errors[1] = fitted.prior, _rms(fitted.posterior.mean().numpy() - truth)
    assert errors[1] < 0.8 * errors[0]
    assert errors[1] < 0.1
    assert priors[1].growth_sd == pytest.approx(float(truth.std()), abs=0.07)
    assert priors[1].sizing.relative_sd == pytest.approx(0.04, abs=0.012)


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2)))


def test_joint_fit_objective_is_each_tails_marginal_likelihood_by_laplace() -> None:
    """InspectedTails.negative_log_marginal at each tail's mode against -log of the marginal
    likelihood integrated on a dense grid (Paris' closed form): within 0.03 nats (measured 0.014-0.019: Gauss-Newton curvature, Euler against the closed form), where the
    joint density at the mode (the joint mode's objective) is off by over a nat, and by a
    different amount per tail: the difference that biased the joint mode's weights."""
    model = CrackGrowthModel(ModelSpec(kernel="physics", law=LAW))
    flights, tails = [1000, 2500], 3
    true_z, noise = [0.3, -0.2, 0.0], [(1.05, 0.97), (0.96, 1.02), (1.0, 1.04)]

    def closed_form(z: torch.Tensor, n: int) -> torch.Tensor:
        return paris_closed_form(LAW.initial_crack_m, 100.0, n * torch.exp(z), LAW)

    measured = [
        float(closed_form(torch.tensor(zi), n)) * e
        for zi, errors in zip(true_z, noise, strict=True)
        for n, e in zip(flights, errors, strict=True)
    ]
    loads = LoadHistory(
        torch.full((tails, 3000), 100.0, dtype=torch.float64), torch.full((tails,), 3000)
    )
    obs = Observations(
        torch.arange(tails).repeat_interleave(len(flights)),
        torch.tensor(flights * tails),
        torch.tensor(measured, dtype=torch.float64),
    )
    evidence = TailEvidence(loads, torch.arange(tails), obs, tails)
    prior = TrackingPrior(0.3, SizingError(0.04, 0.0002))
    inspected = InspectedTails.of(evidence, LAW)
    assert inspected is not None

    z = torch.linspace(-2, 2, 40_001, dtype=torch.float64)
    step = float(z[1] - z[0])
    modes, exact, joint_mode = [], [], []
    for i in range(tails):
        log_joint = prior.log_density(z)  # the fleet's N(0, tau**2) with its surprise share
        for n, y in zip(flights, measured[2 * i : 2 * i + 2], strict=True):
            pred = closed_form(z, n)
            sd = prior.sizing.log_sd(pred)
            r = (math.log(y) - torch.log(pred)) / sd
            log_joint = log_joint - 0.5 * r**2 - torch.log(sd) - 0.5 * math.log(2 * math.pi)
        log_joint = torch.nan_to_num(log_joint, nan=-math.inf)
        modes.append(float(z[int(torch.argmax(log_joint))]))
        exact.append(-float(torch.logsumexp(log_joint, 0)) - math.log(step))
        joint_mode.append(-float(log_joint.max()))
    at_mode = torch.tensor(modes, dtype=torch.float64)
    with torch.no_grad():
        laplace = inspected.negative_log_marginal(
            model, at_mode, prior, torch.tensor(prior.growth_mean)
        )
    assert laplace.tolist() == pytest.approx(exact, abs=0.03)
    gaps = np.abs(np.array(joint_mode) - np.array(exact))
    assert gaps.min() > 1.0 and np.ptp(gaps) > 0.05


def test_cracks_past_a_crit_are_growth_data_until_they_run_away() -> None:
    """A crack measured past a_crit still says how fast the tail grew (leaving such cracks out
    kept only the fast tails whose noise came out short: the kernel bent down at long cracks);
    one past ParisLaw.runaway_crack_m says only that it failed.  The kernel's box still ends at
    a_crit, the range a forecast needs."""
    flights = [800, 1600, 2400]
    measured = [0.02, 1.4 * LAW.critical_crack_m, 1.1 * LAW.runaway_crack_m]
    evidence = _constant_load_evidence(measured, flights)
    inspected = InspectedTails.of(evidence, LAW)
    assert inspected is not None
    assert inspected.observations.crack_length_m.tolist() == pytest.approx(measured[:2])
    box = default_box(evidence.loads.stress_range_mpa, LAW, evidence.observations)
    assert box.crack_length_m == (LAW.initial_crack_m, LAW.critical_crack_m)
    runaway_only = _constant_load_evidence(measured[2:], flights[2:])
    assert InspectedTails.of(runaway_only, LAW) is None


def test_a_crack_that_ran_away_says_its_tail_reached_a_crit_not_how_far_past() -> None:
    """A crack measured past ParisLaw.runaway_crack_m (a torn-through panel) is right-censored
    at a_crit: every growth factor that takes the crack past a_crit by then explains it alike,
    so the tail's posterior is its prior cut there, not pushed on to reach the measured length."""
    model = CrackGrowthModel(ModelSpec(kernel="physics", law=LAW))
    prior = TrackingPrior(0.25, SizingError(0.04, 0.0))
    z = torch.linspace(-2.0, 2.0, 401, dtype=torch.float64)
    cracks = paris_closed_form(LAW.initial_crack_m, 100.0, 3000 * torch.exp(z), LAW)
    first_failing = float(z[int(torch.nonzero(cracks.nan_to_num(1.0) >= LAW.critical_crack_m)[0])])
    evidence = _constant_load_evidence([1.1 * LAW.runaway_crack_m], [3000])
    posterior = growth_posterior(model, evidence, prior)
    low, median = posterior.quantiles([0.05, 0.5])[0].tolist()
    # the prior N(0, 0.25**2) cut at the failing factor (2.4 sd out): its median lies ~0.05
    # above it; read as a 0.275 m crack, the factor went 0.17 above (old code)
    assert first_failing - 0.05 < low < median < first_failing + 0.1


def test_fleet_spread_is_found_when_it_is_narrower_than_the_grid() -> None:
    """Gaussian likelihoods (sd 0.12) about z_i ~ N(0, 0.1**2) on grids as build_grid makes
    them where a likelihood is narrow against the coarse spacing (0.2): the coarse grid plus 25
    points over +-0.3 about the coarse point nearest its peak, 0.025 apart.  A prior far
    narrower than that spacing summed to about twice one on them, which inflated the evidence of
    a small tau (as after a joint fit on a fleet with tau 0.1 under 8 % sizing error,
    benchmarks/RESULTS.md).  The empirical-Bayes tau is ~0.1; with the prior summed on each
    tail's own grid it came out 0.0001."""
    rng = np.random.default_rng(3)
    tails, sd, tau = 400, 0.12, 0.1
    peaks = rng.normal(0.3, tau, tails) + rng.normal(0.0, sd, tails)
    coarse = np.linspace(-2.0, 2.0, 21)
    fine = np.round(peaks / 0.2)[:, None] * 0.2 + np.linspace(-0.3, 0.3, 25)
    z = np.sort(np.concatenate([np.tile(coarse, (tails, 1)), fine], axis=1), axis=1)
    log_likelihood = -0.5 * ((z - peaks[:, None]) / sd) ** 2
    mean, estimate = estimate_growth_prior(
        torch.from_numpy(log_likelihood), torch.from_numpy(z), torch.ones(tails, dtype=torch.bool)
    )
    assert estimate == pytest.approx(tau, abs=0.025)
    # the fleet's own rate (here 0.3 over the model's) is the prior's mean, not a spread
    assert mean == pytest.approx(0.3, abs=0.03)


def test_a_fresh_tracked_posterior_is_the_one_computed_anew() -> None:
    """fit_tracked's posterior is growth_posterior's own, bit for bit, where no sizing error was
    estimated after its grid (one inspection a tail: TrackedFit.fresh); where one was (two a
    tail), it is not fresh and callers compute it anew."""
    fleet = generate_fleet(FleetConfig(aircraft_per_mix=4, years=2, seed=3, growth_scatter=0.25))
    fpy = fleet.config.flights_per_year
    for flights, fresh in (([fpy], True), ([fpy, 2 * fpy], False)):
        sample = inspect_at(fleet, np.arange(fleet.size), np.array(flights), 0.04, seed=1)
        evidence = TailEvidence(
            sample.loads, torch.arange(fleet.size), sample.observations, fleet.size
        )
        model = CrackGrowthModel(ModelSpec(kernel="physics", law=fleet.config.law))
        fitted = fit_tracked(model, evidence, SizingError())
        assert fitted.fresh is fresh
        anew = growth_posterior(model, evidence, fitted.prior)
        same = torch.equal(anew.z, fitted.posterior.z) and torch.equal(
            anew.mass, fitted.posterior.mass
        )
        assert same is fresh
