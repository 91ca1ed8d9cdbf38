"""The fleet prior's evidence as matrix-vector products against its definition: each tail's
log-likelihood interpolated onto the dense grid by scipy's PchipInterpolator, the prior's
integral a logsumexp, mu by the same EM, tau by the same search."""

import numpy as np
import torch
from scipy.interpolate import PchipInterpolator

from model import fleet_spread
from model.fleet_spread import EM_STEPS, EVIDENCE_POINTS, estimate_growth_prior
from model.scalar_search import maximise_scale
from model.tracking import MAX_GROWTH_SD, surprise_prior


def _reference_evidence(log_likelihood: np.ndarray, z: np.ndarray):
    """log evidence at tau (mu at its best by EM) the direct way (model.fleet_spread before
    it kept the likelihoods scaled to their peaks)."""
    lo, hi = z.min(axis=1).max(), z.max(axis=1).min()
    dense = np.linspace(lo, hi, EVIDENCE_POINTS)
    rows = []
    for x, y in zip(z, log_likelihood, strict=True):
        keep = np.concatenate(([True], np.diff(x) > 0))
        rows.append(PchipInterpolator(x[keep], np.maximum(y[keep], -1e6))(dense))
    ll, grid = torch.from_numpy(np.stack(rows)), torch.from_numpy(dense)
    spacing = float(grid[1] - grid[0])

    def marginals(mu: float, tau: float) -> torch.Tensor:
        prior = surprise_prior(grid - mu, max(tau, spacing))[0]
        return ll + (prior - torch.logsumexp(prior, dim=0))[None, :]

    def at(tau: float) -> tuple[float, float]:
        mu = float(grid[int(ll.sum(dim=0).argmax())])
        for _ in range(EM_STEPS):
            moved = float((torch.softmax(marginals(mu, tau), dim=1) * grid).sum(dim=1).mean())
            if abs(moved - mu) < 1e-5:
                mu = moved
                break
            mu = moved
        return float(torch.logsumexp(marginals(mu, tau), dim=1).sum()), mu

    return at


def _tails(seed: int, tails: int = 120):
    """Tails' log-likelihoods of z on grids of their own (repeated values in some), peaked about
    each tail's factor with its own sharpness, a few far out."""
    rng = np.random.default_rng(seed)
    peaks = rng.normal(0.05, 0.25, tails)
    peaks[:3] = [1.2, -1.0, 0.9]
    width = rng.uniform(0.03, 0.3, tails)
    z = np.sort(rng.uniform(-2.5, 2.5, (tails, 46)), axis=1)
    z[:, 0], z[:, -1] = -2.6, 2.6
    z[::7, 10] = z[::7, 9]  # a grid value repeated
    log_likelihood = -0.5 * ((z - peaks[:, None]) / width[:, None]) ** 2
    return log_likelihood, z


def test_mu_and_tau_are_the_definitions_bit_for_bit_and_the_evidence_to_rounding() -> None:
    for seed in (0, 1):
        log_likelihood, z = _tails(seed)
        at = _reference_evidence(log_likelihood, z)
        scan = [0.0, *np.geomspace(0.01, MAX_GROWTH_SD, 24).tolist()]
        tau = maximise_scale(lambda t, at=at: at(t)[0], scan, 30)
        mu = at(tau)[1]
        informed = torch.ones(len(z), dtype=torch.bool)
        ll, grid = torch.from_numpy(log_likelihood), torch.from_numpy(z)
        got_mu, got_tau = estimate_growth_prior(ll, grid, informed)
        # the search's comparisons agree with the definition's, and mu is taken its way
        assert got_tau == tau
        assert got_mu == mu
        evidence = fleet_spread._Evidence.of(ll, grid, informed)
        for spread in (0.0, 0.004, tau, 0.7):
            assert abs(evidence.at(spread) - at(spread)[0]) <= 1e-10 * abs(at(spread)[0])
