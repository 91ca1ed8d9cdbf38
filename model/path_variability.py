"""How far forecasts drift from what later measurements show, beyond what the fitted posterior
says: the part of a tail's future that neither its own growth factor nor the shared model's
posterior carries.

Why.  A model fitted to the early part of each crack's life extrapolates the rest: its growth
factor per tail, and a shared law (C, m, the kernel) fitted over the crack sizes seen so far.
Real cracks do not follow one law that far (a specimen's geometry factor grows with the crack,
its rate drifts along its path), and the posterior knows nothing of it.  Measured on Hudak's
alloy-A specimens (benchmarks/real_data.py), measurements up to 40,000 cycles: the posterior's
[p05, p95] held 63 % of the later measurements.

Model.  A forecast's log deviates from the truth by ~N(0, path_sd**2 d**4) beyond the posterior,
d = ln(a / a_last) the log growth it extrapolates since the tail's latest measurement (since its
initial crack where it has none; model.path_drift gives the exact map, which keeps every path
growing): a law whose log growth rate is off by an amount that grows with the distance from the
cracks it was fitted on (an exponent, a geometry factor) accumulates a log error growing as
d**2.  Against the spread growing as d (a rate off by a constant factor, which each tail's own
factor already carries): on alloy-A, with the drift estimated from half records, the [p05, p95]
held 97 / 97 / 75 / 66 % of the later measurements from 30 / 40 / 50 / 60 thousand cycles on,
against 78 / 93 / 43 / 46 %.  path_sd is estimated from the inspections themselves, the way
forecasts are made (leave-future-out): the model is refitted (by the caller's `refit`) on the
first third of each tail's measurements and again on the first half, the rest is predicted from
each origin, and the likelihood of all those predictions under their predictive variance and
that map's drift is read over s (_log_likelihoods).  path_sd is the root of s**2's posterior
mean under a uniform prior on [0, MAX_PATH_SD] (the drift's uncertainty integrated), not the
likelihood's maximum: the held-out growth is short (d of 0.05-0.4 where a forecast to a_crit
extrapolates 0.3-0.6), a drift growing as d**2 hides under the sizing error there, and the
maximum then sat at 0 with the data allowing far more (Hudak's alloy-A with specimens inspected
to 0-60 thousand cycles: maximum 0, posterior 90th percentile 0.6; the bands held 79 % of the
later measurements, the deeply inspected specimens' misses all above p95).  The held-out log
likelihood that compares two kernels (model.kernel_choice) is the maximum's.  Why two origins: a
forecast extrapolates further than half a tail's record does, and the drift estimated from the
halves alone saw too little of it (alloy-A from 50 / 60 thousand cycles on: 75 / 66 % held; with
both origins 91 / 85 %, and 97 / 97 % from 30 / 40 thousand as before; from the first third
alone, at 30 thousand cycles (one measurement a specimen kept) the kernel choice flipped to the
hybrid, whose lives erred 4.7 % against the physics' 3.2 %).  The drift's draws are symmetric:
it widens the bands and leaves the median where the posterior puts it.  A fleet whose model
holds (the generator's with its own physics) gives ~0, and nothing changes.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import torch
from torch import Tensor

from model.evaluation import select_rows
from model.fleet_sampling import crack_samples
from model.hybrid import CrackGrowthModel
from model.scalar_search import maximise_scale
from model.tracking import GrowthPosterior, TailEvidence, TrackingPrior
from model.tracking_grid import growth_posterior
from model.uncertainty import LaplacePosterior

# inspected tails the leave-future-out refits read at most (a seeded random choice of them where
# more are inspected): they estimate one scalar drift and compare two kernels' held-out
# likelihoods, which a hundred tails' later measurements settle; reading all 300 of a fleet
# inspected twice took a retrain from 58 to 106 s (benchmarks/tracking_service.py)
MAX_REFIT_TAILS = 100
# held-out measurements needed before path_sd is estimated (fewer: 0, none assumed)
MIN_HELD_OUT = 5
MAX_PATH_SD = 20.0
# points of the uniform grid over [0, MAX_PATH_SD] the drift's posterior is summed on
POSTERIOR_POINTS = 1001
# samples of each held-out measurement's predictive distribution
HELD_OUT_SAMPLES = 64
# cells a downward drift's move is summed over, and scales of s computed at once
# (_log_likelihoods)
DOWN_CELLS = 96
SCALES_AT_ONCE = 64


@dataclass(frozen=True)
class FittedForTracking:
    """What a refit returns: the model, its weights' posterior and its fleet prior; growth,
    where the fit has it, each tail's growth posterior as growth_posterior(model, evidence,
    prior) gives it on the evidence fitted (model.tracking_fit.TrackedFit.fresh), so that
    _held_out need not march its grid again."""

    model: CrackGrowthModel
    weights: LaplacePosterior | None
    prior: TrackingPrior
    growth: GrowthPosterior | None = None


@dataclass(frozen=True)
class PathFit:
    """path_sd and the log likelihood of the held-out measurements at the drift that maximises
    it (None: too few held out to say), which compares two models on the same later
    measurements."""

    path_sd: float
    held_out_log_likelihood: float | None


# forecast origins: the share of each tail's measurements a refit keeps (module docstring)
ORIGINS = (1 / 3, 1 / 2)


def split_measurements(
    evidence: TailEvidence, critical_crack_m: float, kept_share: float = 0.5
) -> tuple[Tensor, Tensor, Tensor]:
    """(held, previous, kept): of each row with two or more measured cracks below a_crit, the
    later ones (held) past the first ceil(kept_share n) (at least one) with, for each, the
    latest of those (previous); and the mask of the observations left to fit and condition
    on."""
    obs = evidence.observations
    measured = obs.measured & (obs.crack_length_m.double() < critical_crack_m)
    held, previous = [], []
    for row in torch.unique(obs.aircraft[measured]).tolist():
        index = torch.nonzero(measured & (obs.aircraft == row)).squeeze(1)
        if len(index) >= 2:
            order = index[torch.argsort(obs.flights[index], stable=True)].tolist()
            earlier = min(max(math.ceil(kept_share * len(order) - 1e-9), 1), len(order) - 1)
            held += order[earlier:]
            previous += [order[earlier - 1]] * (len(order) - earlier)
    kept = torch.ones(len(obs.aircraft), dtype=torch.bool)
    kept[held] = False
    return torch.tensor(held, dtype=torch.long), torch.tensor(previous, dtype=torch.long), kept


def earlier_repeats(evidence: TailEvidence, critical_crack_m: float) -> bool:
    """Whether some tail the refits read (refit_sample) keeps two or more measured cracks in
    the earlier part of its record at the latest origin: only then can a refit learn from a
    tail's own growth between its measurements, as the full fit of a learned kernel does
    (model.kernel_choice)."""
    evidence = refit_sample(evidence)
    obs = evidence.observations
    kept = split_measurements(evidence, critical_crack_m, max(ORIGINS))[2]
    measured = kept & obs.measured & (obs.crack_length_m.double() < critical_crack_m)
    counts = torch.bincount(evidence.row_tail[obs.aircraft[measured]], minlength=evidence.tails)
    return bool((counts >= 2).any())


def estimate_path_sd(
    refit: Callable[[TailEvidence], FittedForTracking],
    evidence: TailEvidence,
    critical_crack_m: float,
) -> PathFit:
    """path_sd (its posterior, _drift_fit) from each tail's later measurements predicted by
    `refit` on its earlier ones, from every origin in ORIGINS (module docstring); 0.0 with
    fewer than MIN_HELD_OUT held out."""
    evidence = refit_sample(evidence)
    parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    splits: list[Tensor] = []
    for share in ORIGINS:
        split = split_measurements(evidence, critical_crack_m, share)
        held = split[0]
        if len(held) >= MIN_HELD_OUT and not any(torch.equal(held, h) for h in splits):
            splits.append(held)  # two measurements a tail: both origins are one split
            parts.append(_held_out(refit, evidence, split))
    if not parts:
        return PathFit(0.0, None)
    residual, variance, growth = (np.concatenate(column) for column in zip(*parts, strict=True))
    return _drift_fit(residual, variance, growth)


def refit_sample(
    evidence: TailEvidence, limit: int = MAX_REFIT_TAILS, seed: int = 0
) -> TailEvidence:
    """The evidence of at most `limit` inspected tails, chosen at random (seeded, so that two
    kernels' refits read the same ones), re-indexed 0..limit-1; all of it where fewer are
    inspected."""
    informed = torch.nonzero(evidence.informed).squeeze(1).numpy()
    if len(informed) <= limit:
        return evidence
    chosen = np.sort(np.random.default_rng(seed).choice(informed, limit, replace=False))
    row_tail = evidence.row_tail.numpy()
    rows = np.flatnonzero(np.isin(row_tail, chosen))
    loads, observations = select_rows(evidence.loads, evidence.observations, rows)
    tail = torch.from_numpy(np.searchsorted(chosen, row_tail[rows]))
    return TailEvidence(loads, tail, observations, limit)


def _held_out(
    refit: Callable[[TailEvidence], FittedForTracking],
    evidence: TailEvidence,
    split: tuple[Tensor, Tensor, Tensor],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(residual, predictive variance, log growth extrapolated) of the held-out measurements
    of one origin's split (split_measurements), in the log."""
    held, previous, kept = split
    obs = evidence.observations
    earlier = replace(evidence, observations=obs.subset(kept))
    fitted = refit(earlier)
    law = fitted.model.spec.law
    posterior = fitted.growth
    if posterior is None:
        posterior = growth_posterior(fitted.model, earlier, fitted.prior)
    rows = obs.aircraft[held]
    loads = replace(evidence.loads.select(rows), lengths=obs.flights[held].clone())
    factors = torch.exp(posterior.sample(HELD_OUT_SAMPLES, seed=0))[:, evidence.row_tail[rows]]
    cracks = crack_samples(
        fitted.model,
        fitted.weights,
        loads,
        loads.initial_or(law.initial_crack_m),
        samples=HELD_OUT_SAMPLES,
        seed=0,
        growth_factor=factors,
    )
    log_a = torch.log(cracks.clamp_min(1e-12))
    centre = log_a.median(dim=0).values
    variance = log_a.var(dim=0) + fitted.prior.sizing.log_sd(centre.exp()) ** 2
    residual = torch.log(obs.crack_length_m[held].double()) - centre
    growth = (centre - torch.log(obs.crack_length_m[previous].double())).clamp_min(1e-6)
    return residual.numpy(), variance.numpy(), growth.numpy()


def _drift_fit(residual: np.ndarray, variance: np.ndarray, growth: np.ndarray) -> PathFit:
    """path_sd: the root posterior mean of s**2 (module docstring), and the held-out log
    likelihood (_log_likelihoods) at its maximum over s in [0, MAX_PATH_SD]."""
    r, v, d = (
        torch.from_numpy(np.asarray(x, dtype=np.float64)) for x in (residual, variance, growth)
    )

    def log_lik(s: float) -> float:
        return float(_log_likelihoods(r, v, d, torch.tensor([s], dtype=torch.float64))[0])

    best = maximise_scale(log_lik, [0.0, *np.geomspace(1e-3, MAX_PATH_SD, 40).tolist()])
    scale = torch.linspace(0.0, MAX_PATH_SD, POSTERIOR_POINTS, dtype=torch.float64)
    log_post = _log_likelihoods(r, v, d, scale)
    weight = torch.exp(log_post - log_post.max())
    mean_square = float(torch.sum(weight * scale**2) / torch.sum(weight))
    return PathFit(math.sqrt(mean_square), log_lik(best))


def _log_likelihoods(residual: Tensor, variance: Tensor, growth: Tensor, scales: Tensor) -> Tensor:
    """(len(scales),) the sum over held-out measurements of log p(residual | s): a residual is
    the drift's move of the log growth d (model.path_drift.moved_log_growth at c = s z, z ~ N(0,
    1)) plus N(0, variance).  Upward (z > 0) the move s z d**2 is normal: its convolution with
    the noise is closed-form.  Downward it lies in (-d, 0), |c| = -move / (d + move)**2: its
    mass in each of DOWN_CELLS cells, exact from that, is set at the cell's middle (the cells
    finer near 0, where a small s puts it all)."""
    r, v, d = residual[None, :], variance[None, :], growth[None, :]
    edges = -d.T * (1 - torch.linspace(0, 1, DOWN_CELLS + 1, dtype=torch.float64)) ** 2
    down_c = -edges / (d.T + edges) ** 2  # (n, cells + 1): inf at -d, 0 at 0
    middle = 0.5 * (edges[:, 1:] + edges[:, :-1])
    out = torch.empty(len(scales), dtype=torch.float64)
    for start in range(0, len(scales), SCALES_AT_ONCE):
        s = scales[start : start + SCALES_AT_ONCE, None].clamp_min(1e-12)
        spread = s * d**2
        total = spread**2 + v
        up = _log_normal(r, total) + torch.special.log_ndtr(r * spread / torch.sqrt(v * total))
        below = torch.special.ndtr(-down_c[None] / s[:, :, None])  # P(move <= edge)
        mass = torch.log(below[..., 1:] - below[..., :-1])
        down = torch.logsumexp(mass + _log_normal(r[..., None] - middle[None], v[..., None]), -1)
        out[start : start + SCALES_AT_ONCE] = torch.logaddexp(up, down).sum(dim=1)
    return out


def _log_normal(x: Tensor, variance: Tensor) -> Tensor:
    return -0.5 * (x**2 / variance + torch.log(2 * math.pi * variance))
