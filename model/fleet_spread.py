"""The fleet prior of individual aircraft tracking: its mean and spread (mu, tau) from the
inspected tails' likelihoods by empirical Bayes, and the spread's posterior that a tail never
inspected is drawn from (model.tracking's module docstring says why)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from model.monotone_cubic import pchip_rows
from model.scalar_search import maximise_scale
from model.tracking import MAX_GROWTH_SD, surprise_log_density

# points of the common grid the evidence integrates on (estimate_growth_prior): 0.005 apart over
# [-2, 2], which resolves a prior down to tau ~0.01, half the least spread read as scatter
EVIDENCE_POINTS = 801


def estimate_growth_prior(
    log_likelihood: Tensor, z: Tensor, informed: Tensor
) -> tuple[float, float]:
    """Empirical-Bayes (mu, tau): argmax of sum_i log int L_i(z) N(z; mu, tau**2) dz over the
    informed tails; tau by golden-section search on [0, MAX_GROWTH_SD] after a coarse scan, mu
    at each tau by EM (the mean of the tails' posterior means).  (0, 0) without an informed
    tail.

    Each tail's grid is fine only around its own likelihood peak, so a prior narrower than the
    coarse spacing fell between its points: summed there, it integrated to several times one
    and inflated the evidence of a small tau (4 % of a fleet with tau 0.1 under 8 % sizing
    error: tau came out 0.0001, every tail at the fleet's rate and the bands holding 29 %).  The
    integral is therefore taken on one dense grid, each tail's log-likelihood interpolated onto
    it (monotone cubic: it is smooth in z), with the prior renormalised over the grid."""
    if not bool(informed.any()):
        return 0.0, 0.0
    evidence = _Evidence.of(log_likelihood, z, informed)
    scan = [0.0, *np.geomspace(0.01, MAX_GROWTH_SD, 24).tolist()]
    tau = maximise_scale(evidence.at, scan, 30)
    return evidence.best_mean(tau, exact=True), tau


# The prior of the fleet spread tau of ln growth rate: half-normal with sd 0.3.  Replicate
# specimens of one alloy under one load scatter by tens of percent in rate (Virkler 1979's
# 68 panels: ln-rate sd ~0.2; Hudak 1978), so 0.3 admits every spread seen and more, and it
# leaves a spread the inspections barely tell (one round at year 1) wide rather than at 0.
SPREAD_PRIOR_SD = 0.3
# spreads the posterior is read at, geometric over [SPREAD_GRID_LOW, MAX_GROWTH_SD]: a spread
# below the least one differs from it by less than any inspection resolves
SPREAD_POINTS = 32
SPREAD_GRID_LOW = 0.002


def _spread_grid() -> tuple[np.ndarray, np.ndarray]:
    """The spreads tau_k the posterior is read at and their trapezoid widths."""
    taus = np.geomspace(SPREAD_GRID_LOW, MAX_GROWTH_SD, SPREAD_POINTS)
    gaps = np.diff(taus)
    return taus, 0.5 * (np.concatenate(([0.0], gaps)) + np.concatenate((gaps, [0.0])))


def spread_prior() -> tuple[tuple[float, float], ...]:
    """(tau_k, weight_k): the spread's prior alone (half-normal SPREAD_PRIOR_SD) on
    spread_posterior's points: what a location's tails are drawn from before any of them is
    inspected (its analysis, model.posterior.analysis)."""
    taus, width = _spread_grid()
    weight = np.exp(-0.5 * (taus / SPREAD_PRIOR_SD) ** 2) * width
    weight /= weight.sum()
    return tuple((float(t), float(w)) for t, w in zip(taus, weight, strict=True))


def spread_posterior(
    log_likelihood: Tensor, z: Tensor, informed: Tensor, mu: float
) -> tuple[tuple[float, float], ...]:
    """spread_with_evidence's spread alone."""
    return spread_with_evidence(log_likelihood, z, informed, mu)[0]


def spread_with_evidence(
    log_likelihood: Tensor, z: Tensor, informed: Tensor, mu: float
) -> tuple[tuple[tuple[float, float], ...], float]:
    """(sd_k, weight_k): a new tail's ln factor is N(mu_k, sd_k**2) with probability weight_k,
    its posterior predictive given the inspected tails (model.tracking): the fleet spread's
    posterior at SPREAD_POINTS spreads tau_k, the profile of the evidence (mu at its best
    mu_k for each spread, from `mu`) times the half-normal prior SPREAD_PRIOR_SD with trapezoid
    weights in tau, and sd_k**2 = tau_k**2 + var(mu | tau_k), so the mean's own uncertainty
    counts too (it matters where the spread is small against what the tails tell); and the
    log evidence of the tails' likelihoods under the whole prior (tau integrated, mu at its
    best), which weighs one sizing error against another (model.tracking_fit)."""
    evidence = _Evidence.of(log_likelihood, z, informed)
    taus, width = _spread_grid()
    means = [evidence.best_mean(float(t), start=mu) for t in taus]
    sds = [
        math.sqrt(t**2 + evidence.mean_variance(m, float(t)))
        for t, m in zip(taus, means, strict=True)
    ]
    log_post = np.array([evidence.at(float(t), start=m) for t, m in zip(taus, means, strict=True)])
    log_post -= 0.5 * (taus / SPREAD_PRIOR_SD) ** 2
    weight = np.exp(log_post - log_post.max()) * width
    total = float(weight.sum())
    weight /= total
    # the half-normal's normalisation on the grid, so that evidences under different data compare
    prior_total = float((np.exp(-0.5 * (taus / SPREAD_PRIOR_SD) ** 2) * width).sum())
    log_evidence = float(log_post.max()) + math.log(total) - math.log(prior_total)
    spread = tuple((float(sd), float(w)) for sd, w in zip(sds, weight, strict=True))
    return spread, log_evidence


# EM steps of the fleet mean at one tau (estimate_growth_prior); each moves it by the tails'
# mean posterior shift, which shrinks geometrically
EM_STEPS = 50


@dataclass(frozen=True)
class _Evidence:
    """The informed tails' log-likelihoods on one dense grid (estimate_growth_prior's
    docstring), and the log evidence of a fleet prior N(mu, tau**2) on it.

    Each tail's likelihood is kept scaled to its peak, exp(log L_i - peak_i), so that a prior's
    integral over the grid is one matrix-vector product, not a logsumexp over (tails, points)
    (the scan, the golden-section search and EM evaluate ~700 priors per estimate: on 240
    tails 0.9-1.0 CPU s an estimate that way, 0.15 s this way, the same to rounding; the mu
    returned alone is taken the former way, to its bits: best_mean).  The prior's wide share
    (model.tracking.surprise_log_density) keeps every tail's integral far from underflow: at its
    peak, the scaled likelihood is one."""

    log_likelihood: Tensor  # (tails, EVIDENCE_POINTS) log L_i
    peak: Tensor  # (tails,) max_z log L_i
    likelihood: Tensor  # (tails, EVIDENCE_POINTS) L_i / max_z L_i
    z: Tensor  # (EVIDENCE_POINTS,)
    pooled_peak: float  # where the tails' likelihoods together peak: EM's default start

    @classmethod
    def of(cls, log_likelihood: Tensor, z: Tensor, informed: Tensor) -> _Evidence:
        dense, grid = _dense_log_likelihood(log_likelihood[informed], z[informed])
        peak = dense.max(dim=1).values
        pooled_peak = float(grid[int(dense.sum(dim=0).argmax())])
        return cls(dense, peak, torch.exp(dense - peak[:, None]), grid, pooled_peak)

    def log_prior(self, mu: float, tau: float) -> Tensor:
        """(points,) log N(mu, tau**2) (with its surprise share) renormalised over the grid.  A
        prior narrower than the grid as one as wide as its spacing: a point mass on the nearest
        point read mu off the grid (0.005 steps; a fleet's rate 0.5 % off, and its bands held
        81 %)."""
        spacing = float(self.z[1] - self.z[0])
        log_prior = surprise_log_density(self.z - mu, max(tau, spacing))
        return log_prior - torch.logsumexp(log_prior, dim=0)

    def best_mean(self, tau: float, start: float | None = None, exact: bool = False) -> float:
        """mu at its best for this tau, by EM from `start` (else the pooled likelihood's peak).
        exact: each posterior as a softmax over the grid, as before the scaled likelihoods,
        to its bits: the mu returned (a retrain's refits follow a change in its last bit to
        other optima: the default location's path sd 0.850 became 0.334)."""
        mu = self.pooled_peak if start is None else start
        for _ in range(EM_STEPS):
            log_prior = self.log_prior(mu, tau)
            if exact:
                weight = torch.softmax(self.log_likelihood + log_prior[None, :], dim=1)
                moved = float((weight * self.z[None, :]).sum(dim=1).mean())
            else:
                prior = torch.exp(log_prior)
                means = (self.likelihood @ (prior * self.z)) / (self.likelihood @ prior)
                moved = float(means.mean())
            if abs(moved - mu) < 1e-5:
                return moved
            mu = moved
        return mu

    def mean_variance(self, mu: float, tau: float) -> float:
        """var(mu | tau) under a flat prior on mu, by the information the tails carry about it
        (Louis' identity: sum_i (1 - v_i / tau**2) / tau**2, v_i tail i's posterior variance
        under N(mu, tau**2); for Gaussian likelihoods 1 / sum_i 1 / (tau**2 + s_i**2))."""
        scale = max(tau, float(self.z[1] - self.z[0]))
        gaussian = -0.5 * ((self.z - mu) / scale) ** 2  # the identity's prior: no surprise share
        weight = torch.softmax(self.log_likelihood + gaussian[None, :], dim=1)
        mean = (weight * self.z[None, :]).sum(dim=1)
        variance = (weight * self.z[None, :] ** 2).sum(dim=1) - mean**2
        # each tail's share clipped at none (a flat likelihood on a coarse grid can read a
        # posterior wider than its prior), the variance at the spreads' range: tails that
        # tell nothing of mu leave it anywhere in it
        information = float(((1 - variance / scale**2).clamp_min(0) / scale**2).sum())
        return min(1 / information, MAX_GROWTH_SD**2) if information > 0 else MAX_GROWTH_SD**2

    def at(self, tau: float, start: float | None = None) -> float:
        """The log evidence at tau, mu at its best."""
        mu = self.best_mean(tau, start)
        integral = self.likelihood @ torch.exp(self.log_prior(mu, tau))
        return float((self.peak + torch.log(integral)).sum())


def _dense_log_likelihood(log_likelihood: Tensor, z: Tensor) -> tuple[Tensor, Tensor]:
    """Each tail's log-likelihood (tails, EVIDENCE_POINTS) on one dense grid of z over the span
    every tail's own grid covers.  A grid value repeated in a tail's grid is read once (its
    first), so tails are interpolated in groups of as many distinct values."""
    x, y = z.numpy(), log_likelihood.numpy()
    lo, hi = float(x.min(axis=1).max()), float(x.max(axis=1).min())
    dense = np.linspace(lo, hi, EVIDENCE_POINTS)
    distinct = np.concatenate([np.ones((len(x), 1), bool), np.diff(x, axis=1) > 0], axis=1)
    values = np.maximum(y, -1e6)  # an impossible grid value, finite for the fit
    counts = distinct.sum(axis=1)
    out = np.empty((len(x), EVIDENCE_POINTS))
    for n in np.unique(counts):
        rows = np.flatnonzero(counts == n)
        kept = distinct[rows]
        knots = x[rows][kept].reshape(len(rows), n)
        out[rows] = pchip_rows(knots, values[rows][kept].reshape(len(rows), n), dense)
    return torch.from_numpy(out), torch.from_numpy(dense)
