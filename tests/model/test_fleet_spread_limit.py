"""The fleet spread a tail never inspected is drawn with: the spread's posterior, a mixture of
N(mu, tau_k**2) (model.tracking's module docstring), calibrated on fleets drawn from its own
prior."""

import numpy as np
import pytest
import torch

from model.fleet_spread import SPREAD_PRIOR_SD, estimate_growth_prior, spread_posterior
from model.tracking import TAU_FLOOR, SizingError, TrackingPrior
from model.tracking_grid import trapezoid_weights

SIZING = SizingError()


def _gaussian_evidence(rng: np.random.Generator, tails: int, tau: float, noise: float):
    """Each tail's log-likelihood of z on a grid: a Gaussian of sd `noise` about its own
    z_i ~ N(0, tau**2) seen through that noise (what an inspection tells of a tail's factor)."""
    peaks = rng.normal(0.0, tau, tails) + rng.normal(0.0, noise, tails)
    z = np.tile(np.linspace(-3.0, 3.0, 241), (tails, 1))
    log_likelihood = -0.5 * ((z - peaks[:, None]) / noise) ** 2
    return torch.from_numpy(log_likelihood), torch.from_numpy(z)


def _uninspected(rng: np.random.Generator, tails: int, tau: float, noise: float) -> TrackingPrior:
    log_likelihood, z = _gaussian_evidence(rng, tails, tau, noise)
    informed = torch.ones(tails, dtype=torch.bool)
    mean, estimate = estimate_growth_prior(log_likelihood, z, informed)
    spread = spread_posterior(log_likelihood, z, informed, mean)
    return TrackingPrior(estimate, SIZING, growth_mean=mean, uninspected_spread=spread)


def _cdf(prior: TrackingPrior, values: np.ndarray) -> np.ndarray:
    z, log_density = prior.fleet_grid(401)
    mass = torch.exp(log_density) * trapezoid_weights(z[None, :])[0]
    cdf = torch.cumsum(mass, 0) / mass.sum()
    return np.interp(values, z.numpy(), cdf.numpy())


def test_tails_never_inspected_are_calibrated_on_fleets_drawn_from_the_prior() -> None:
    """Forty fleets, each spread drawn from the prior (half-normal, SPREAD_PRIOR_SD), 20
    inspected tails each read to 0.1: a new tail's factor falls in the predictive's 90 % range
    about 90 % of the time, and in each tenth of its distribution about as often, whether the
    fleet scatters much or hardly at all."""
    rng = np.random.default_rng(11)
    pits = []
    for _ in range(40):
        tau = abs(rng.normal(0.0, SPREAD_PRIOR_SD))
        prior = _uninspected(rng, 20, tau, 0.1)
        pits.append(_cdf(prior, rng.normal(0.0, tau, 50)))
    pit = np.concatenate(pits)
    assert 0.86 <= float(np.mean((pit > 0.05) & (pit < 0.95))) <= 0.94
    tenths = np.histogram(pit, bins=10, range=(0, 1))[0] / len(pit)
    assert np.all(np.abs(tenths - 0.1) < 0.035)


def test_a_spread_the_inspections_barely_tell_stays_wide() -> None:
    """Five tails each read to 1.0 in ln factor say little of the spread: the predictive keeps
    most of the prior's width, where the estimate alone may read the spread as none."""
    rng = np.random.default_rng(3)
    vague = _uninspected(rng, 5, 0.2, 1.0)
    told = _uninspected(rng, 200, 0.2, 0.05)
    q_vague = np.interp(
        [0.05, 0.95], _cdf(vague, np.linspace(-3, 3, 2001)), np.linspace(-3, 3, 2001)
    )
    q_told = np.interp([0.05, 0.95], _cdf(told, np.linspace(-3, 3, 2001)), np.linspace(-3, 3, 2001))
    assert float(np.diff(q_vague)[0]) > 1.5 * float(np.diff(q_told)[0])
    assert float(np.diff(q_told)[0]) == pytest.approx(2 * 1.645 * 0.2, rel=0.2)


def test_older_model_files_draw_tails_never_inspected_as_they_did() -> None:
    scattered = TrackingPrior(0.2, SIZING, growth_mean=0.1).to_dict()
    del scattered["uninspected_spread"]
    scattered["growth_sd_upper"] = 0.24  # an earlier release's upper limit
    older = TrackingPrior.from_dict(scattered)
    assert older.uninspected_spread == ((0.24, 1.0),)
    z, log_density = older.fleet_grid(2001)
    mass = torch.exp(log_density) * trapezoid_weights(z[None, :])[0]
    mass = mass / mass.sum()
    assert float((mass * z).sum()) == pytest.approx(0.1, abs=1e-6)
    assert float((mass * (z - 0.1) ** 2).sum().sqrt()) == pytest.approx(0.24, rel=1e-2)
    alike = dict(scattered, growth_sd=1e-6, growth_sd_upper=0.03)  # read as alike: its floor
    assert TrackingPrior.from_dict(alike).uninspected_spread == ()
    z, log_density = TrackingPrior.from_dict(alike).fleet_grid(2001)
    mass = torch.exp(log_density) * trapezoid_weights(z[None, :])[0]
    sd = float((mass / mass.sum() * (z - 0.1) ** 2).sum().sqrt())
    assert sd == pytest.approx(TAU_FLOOR, rel=1e-2)
    fresh = TrackingPrior(0.2, SIZING, uninspected_spread=((0.1, 0.5), (0.3, 0.5)))
    assert TrackingPrior.from_dict(fresh.to_dict()) == fresh
    with pytest.raises(ValueError, match="uninspected_spread"):
        TrackingPrior(0.2, SIZING, uninspected_spread=((0.1, 0.5),))
