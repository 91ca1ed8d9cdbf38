"""The fleet prior of individual aircraft tracking by empirical Bayes: its mean and spread
(mu, tau) from the inspected tails' likelihoods, and the spread's upper confidence limit that
a tail never inspected is drawn with (model.tracking's module docstring says why)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy.interpolate import PchipInterpolator
from torch import Tensor

from model.scalar_search import maximise_scale, upper_limit
from model.tracking import MAX_GROWTH_SD, surprise_prior

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
    return evidence.best_mean(tau), tau


def growth_sd_upper(
    log_likelihood: Tensor, z: Tensor, informed: Tensor, mu: float, tau: float
) -> float:
    """The one-sided 95 % upper confidence limit of the fleet spread whose estimate is (mu,
    tau) (estimate_growth_prior's): where the profile of the evidence, mu at its best for each
    spread, has fallen SPREAD_CONFIDENCE_DROP below its maximum (model.tracking's module
    docstring: what a tail never inspected is drawn with)."""
    evidence = _Evidence.of(log_likelihood, z, informed)
    return upper_limit(
        lambda spread: evidence.at(spread, start=mu), tau, SPREAD_CONFIDENCE_DROP, MAX_GROWTH_SD
    )


# the fall of the log evidence from its maximum that bounds the fleet spread from above: the
# one-sided 95 % limit of a profile likelihood (1.645**2 / 2, Wilks)
SPREAD_CONFIDENCE_DROP = 1.645**2 / 2


# EM steps of the fleet mean at one tau (estimate_growth_prior); each moves it by the tails'
# mean posterior shift, which shrinks geometrically
EM_STEPS = 50


@dataclass(frozen=True)
class _Evidence:
    """The informed tails' log-likelihoods on one dense grid (estimate_growth_prior's
    docstring), and the log evidence of a fleet prior N(mu, tau**2) on it."""

    log_likelihood: Tensor  # (tails, EVIDENCE_POINTS)
    z: Tensor  # (EVIDENCE_POINTS,)

    @classmethod
    def of(cls, log_likelihood: Tensor, z: Tensor, informed: Tensor) -> _Evidence:
        return cls(*_dense_log_likelihood(log_likelihood[informed], z[informed]))

    def log_marginals(self, mu: float, tau: float) -> Tensor:
        """(tails, points) log L_i + log prior.  A prior narrower than the grid as one as wide
        as its spacing: a point mass on the nearest point read mu off the grid (0.005 steps; a
        fleet's rate 0.5 % off, and its bands held 81 %)."""
        spacing = float(self.z[1] - self.z[0])
        prior = surprise_prior(self.z - mu, max(tau, spacing))[0]
        prior = prior - torch.logsumexp(prior, dim=0)
        return self.log_likelihood + prior[None, :]

    def best_mean(self, tau: float, start: float | None = None) -> float:
        """mu at its best for this tau, by EM from `start` (else the pooled likelihood's peak)."""
        mu = float(self.z[int(self.log_likelihood.sum(dim=0).argmax())]) if start is None else start
        for _ in range(EM_STEPS):
            weight = torch.softmax(self.log_marginals(mu, tau), dim=1)
            moved = float((weight * self.z[None, :]).sum(dim=1).mean())
            if abs(moved - mu) < 1e-5:
                return moved
            mu = moved
        return mu

    def at(self, tau: float, start: float | None = None) -> float:
        """The log evidence at tau, mu at its best."""
        mu = self.best_mean(tau, start)
        return float(torch.logsumexp(self.log_marginals(mu, tau), dim=1).sum())


def _dense_log_likelihood(log_likelihood: Tensor, z: Tensor) -> tuple[Tensor, Tensor]:
    """Each tail's log-likelihood (tails, EVIDENCE_POINTS) on one dense grid of z over the span
    every tail's own grid covers."""
    lo, hi = float(z.min(dim=1).values.max()), float(z.max(dim=1).values.min())
    dense = np.linspace(lo, hi, EVIDENCE_POINTS)
    out = np.empty((z.shape[0], EVIDENCE_POINTS))
    for i, (x, y) in enumerate(zip(z.numpy(), log_likelihood.numpy(), strict=True)):
        distinct = np.concatenate(([True], np.diff(x) > 0))
        values = np.maximum(y[distinct], -1e6)  # an impossible grid value, finite for the fit
        out[i] = PchipInterpolator(x[distinct], values)(dense)
    return torch.from_numpy(out), torch.from_numpy(dense)
