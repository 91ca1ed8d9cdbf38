"""Fitting individual aircraft tracking: the fleet prior by empirical Bayes, the sizing error
from repeated measurements, and the hierarchical refit of the shared model (model.tracking
holds the model and the per-tail posteriors)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import torch
from torch import Tensor

from model.hybrid import CrackGrowthModel
from model.integrate import LoadHistory
from model.tracking import (
    MAX_GROWTH_SD,
    Grid,
    GrowthPosterior,
    SizingError,
    TailEvidence,
    TrackingPrior,
    build_grid,
    growth_posterior,
    log_normal_pdf,
    trapezoid_weights,
)
from model.train import TrainConfig, fit

# repeated measurements (beyond each tail's first) needed before the sizing sd is estimated
MIN_SIZING_DOF = 10
# inspected tails needed before the fleet spread is estimated (with one or two, the evidence
# maximum sits at each tail's own deviation); below it the caller's spread stands
MIN_SPREAD_TAILS = 5


def estimate_growth_sd(log_likelihood: Tensor, z: Tensor, informed: Tensor) -> float:
    """Empirical-Bayes tau: argmax over tau of sum_i log int L_i(z) N(z; 0, tau**2) dz over the
    informed tails (golden-section search on [0, MAX_GROWTH_SD] after a coarse scan)."""
    if not bool(informed.any()):
        return 0.0
    ll, zz = log_likelihood[informed], z[informed]
    weights = torch.log(trapezoid_weights(zz).clamp_min(1e-300))
    at_zero = ll.gather(1, torch.argmin(zz.abs(), dim=1, keepdim=True)).squeeze(1)

    def evidence(tau: float) -> float:
        if tau < 1e-4:
            return float(at_zero.sum())
        log_terms = ll + log_normal_pdf(zz, tau) + weights
        return float(torch.logsumexp(log_terms, dim=1).sum())

    scan = [0.0, *np.geomspace(0.01, MAX_GROWTH_SD, 24).tolist()]
    values = [evidence(t) for t in scan]
    best = int(np.argmax(values))
    lo, hi = scan[max(best - 1, 0)], scan[min(best + 1, len(scan) - 1)]
    golden = (math.sqrt(5) - 1) / 2
    for _ in range(30):
        a, b = hi - golden * (hi - lo), lo + golden * (hi - lo)
        if evidence(a) >= evidence(b):
            hi = b
        else:
            lo = a
    tau = 0.5 * (lo + hi)
    return tau if evidence(tau) >= values[best] else scan[best]


def estimate_relative_sizing_sd(
    grid_ll: Tensor, grid: Grid, evidence: TailEvidence, sizing: SizingError
) -> float | None:
    """Relative sizing sd from repeated measurements: the log residuals at each tail's most
    likely z, over (measurements - tails with measurements) degrees of freedom, less the
    absolute part; None where fewer than MIN_SIZING_DOF repeated measurements exist."""
    obs = evidence.observations
    hit = torch.ones(len(obs.aircraft), dtype=torch.bool) if obs.detected is None else obs.detected
    tails = evidence.observation_tail[hit]
    if len(tails) == 0:
        return None
    counts = torch.bincount(tails, minlength=evidence.tails)
    dof = int((counts - 1).clamp_min(0).sum())
    if dof < MIN_SIZING_DOF:
        return None
    best = grid_ll.argmax(dim=1)  # (tails,)
    predicted = grid.predicted[hit].gather(1, best[tails][:, None]).squeeze(1)
    residual = torch.log(obs.crack_length_m[hit].double()) - torch.log(predicted)
    repeated = counts[tails] > 1
    total = float(residual[repeated].pow(2).sum())
    absolute = float(((sizing.absolute_sd_m / predicted[repeated]) ** 2).mean())
    variance = total / dof - absolute
    return math.sqrt(max(variance, 1e-6))


def fit_prior(
    model: CrackGrowthModel,
    evidence: TailEvidence,
    sizing: SizingError,
    *,
    estimate_sizing: bool = True,
    growth_sd: float = 0.0,
) -> tuple[TrackingPrior, Grid]:
    """The fleet prior from the inspected tails (module docstring): tau by empirical Bayes where
    at least MIN_SPREAD_TAILS tails are inspected (else `growth_sd`), the relative sizing sd
    from repeated measurements where there are enough."""
    grid = build_grid(model, evidence, sizing)
    estimated: list[str] = []
    if estimate_sizing:
        relative = estimate_relative_sizing_sd(
            grid.log_likelihood(evidence, sizing), grid, evidence, sizing
        )
        if relative is not None:
            sizing = replace(sizing, relative_sd=relative)
            estimated.append("sizing_relative_sd")
    informed = evidence.informed
    if int(informed.sum()) < MIN_SPREAD_TAILS:
        return TrackingPrior(growth_sd, sizing, tuple(estimated)), grid
    tau = estimate_growth_sd(grid.log_likelihood(evidence, sizing), grid.z, informed)
    return TrackingPrior(tau, sizing, (*estimated, "growth_sd")), grid


# Below this fleet spread of ln growth rate the shared model is not refitted per tail: a fleet
# without scatter keeps exactly the shared fit (and every result of the thesis's world).
REFIT_GROWTH_SD = 0.02


def fit_tracked(
    model: CrackGrowthModel,
    evidence: TailEvidence,
    sizing: SizingError,
    config: TrainConfig | None = None,
    *,
    rounds: int = 1,
    growth_sd: float = 0.0,
) -> tuple[TrackingPrior, GrowthPosterior, LoadHistory]:
    """Hierarchical fit on top of a fitted shared model: the fleet prior and each tail's
    posterior, then (where the fleet scatters, growth_sd > REFIT_GROWTH_SD) `rounds` refits of
    the shared model with each inspected tail at its posterior mean factor, so that tail-to-tail
    scatter is not read as missing physics, re-estimating the prior each time.  The model is
    refitted in place.  Returns the prior, the posteriors and the loads with the factors used
    (what the model's weights were last fitted on).  growth_sd: the fleet spread assumed where
    too few tails are inspected to learn it (fit_prior)."""
    prior, grid = fit_prior(model, evidence, sizing, growth_sd=growth_sd)
    loads = evidence.loads
    learned = bool(model.network_parameters())
    for _ in range(rounds if learned else 0):
        if prior.growth_sd <= REFIT_GROWTH_SD:
            break
        posterior = growth_posterior(model, evidence, prior, grid)
        loads = replace(
            evidence.loads, growth_factor=torch.exp(posterior.mean())[evidence.row_tail]
        )
        fit(model, loads, evidence.observations, config)
        prior, grid = fit_prior(model, evidence, prior.sizing, growth_sd=growth_sd)
    return prior, growth_posterior(model, evidence, prior, grid), loads
