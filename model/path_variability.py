"""Growth that wanders along a crack's path: the part of a tail's future that neither its own
growth factor nor the shared model's posterior carries.

Why.  Replicate specimens of one alloy do not only grow at different rates: each one's rate
drifts along its crack path (local microstructure), so a constant per-tail factor fitted to a
tail's early measurements extrapolates its later cracks with bands far too narrow.  Measured on
Hudak's alloy-A specimens (benchmarks/real_data.py), measurements up to 60,000 cycles: the
[p05, p95] of the constant-factor posterior held 43 % of the later measurements.

Model.  ln(growth rate) drifts like a random walk in ln a, so a crack's log deviates from its
constant-factor path by N(0, path_sd**2 d), d = ln(a / a_last) the log growth since the tail's
latest measurement (since its initial crack where it has none).  path_sd is estimated from the
inspections themselves: each tail's latest measurement is predicted from its earlier ones
(leave-future-out, under the fitted model, its weights' posterior and the fleet prior), and
path_sd maximises the likelihood of those held-out measurements with the predictive variance
plus path_sd**2 d.  A fleet without drift (the generator's) gives ~0, and then nothing changes.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import torch
from torch import Tensor

from model.fleet_sampling import crack_samples
from model.hybrid import CrackGrowthModel
from model.tracking import TailEvidence, TrackingPrior, growth_posterior
from model.uncertainty import LaplacePosterior

# held-out measurements needed before path_sd is estimated (fewer: 0, no drift assumed)
MIN_HELD_OUT = 5
MAX_PATH_SD = 1.0
# samples of each held-out tail's predictive distribution
HELD_OUT_SAMPLES = 64


def _held_out(evidence: TailEvidence, critical_crack_m: float) -> tuple[Tensor, Tensor, Tensor]:
    """(held, previous, kept): per row with two or more measured cracks below a_crit, the
    index of its latest such observation and of the one before it; and the mask of the
    observations kept to condition on (all but the held ones)."""
    obs = evidence.observations
    measured = obs.crack_length_m.double() < critical_crack_m
    if obs.detected is not None:
        measured &= obs.detected
    held, previous = [], []
    for row in torch.unique(obs.aircraft[measured]).tolist():
        index = torch.nonzero(measured & (obs.aircraft == row)).squeeze(1)
        if len(index) >= 2:
            order = index[torch.argsort(obs.flights[index], stable=True)]
            held.append(int(order[-1]))
            previous.append(int(order[-2]))
    kept = torch.ones(len(obs.aircraft), dtype=torch.bool)
    kept[held] = False
    return torch.tensor(held, dtype=torch.long), torch.tensor(previous, dtype=torch.long), kept


def estimate_path_sd(
    model: CrackGrowthModel,
    weights: LaplacePosterior | None,
    evidence: TailEvidence,
    prior: TrackingPrior,
) -> float:
    """path_sd by leave-future-out maximum likelihood (module docstring); 0.0 with fewer than
    MIN_HELD_OUT tails measured twice or more."""
    law = model.spec.law
    held, previous, kept = _held_out(evidence, law.critical_crack_m)
    if len(held) < MIN_HELD_OUT:
        return 0.0
    obs = evidence.observations
    earlier = replace(evidence, observations=obs.subset(kept))
    posterior = growth_posterior(model, earlier, prior)
    rows = obs.aircraft[held]
    loads = evidence.loads.select(rows)
    loads = replace(loads, lengths=obs.flights[held].clone())
    factors = torch.exp(posterior.sample(HELD_OUT_SAMPLES, seed=0))[:, evidence.row_tail[rows]]
    cracks = crack_samples(
        model,
        weights,
        loads,
        loads.initial_or(law.initial_crack_m),
        samples=HELD_OUT_SAMPLES,
        seed=0,
        growth_factor=factors,
    )
    log_a = torch.log(cracks.clamp_min(1e-12))
    centre = log_a.median(dim=0).values
    variance = log_a.var(dim=0) + prior.sizing.log_sd(centre.exp()) ** 2
    residual = torch.log(obs.crack_length_m[held].double()) - centre
    growth = (centre - torch.log(obs.crack_length_m[previous].double())).clamp_min(1e-6)
    return _max_likelihood_sd(residual.numpy(), variance.numpy(), growth.numpy())


def _max_likelihood_sd(residual: np.ndarray, variance: np.ndarray, growth: np.ndarray) -> float:
    """argmax over s in [0, MAX_PATH_SD] of sum log N(residual; 0, variance + s**2 growth)."""

    def log_lik(s: float) -> float:
        total = variance + s**2 * growth
        return float(-0.5 * np.sum(residual**2 / total + np.log(total)))

    scan = [0.0, *np.geomspace(1e-3, MAX_PATH_SD, 40).tolist()]
    values = [log_lik(s) for s in scan]
    best = int(np.argmax(values))
    lo, hi = scan[max(best - 1, 0)], scan[min(best + 1, len(scan) - 1)]
    golden = (math.sqrt(5) - 1) / 2
    for _ in range(40):
        a, b = hi - golden * (hi - lo), lo + golden * (hi - lo)
        if log_lik(a) >= log_lik(b):
            hi = b
        else:
            lo = a
    s = 0.5 * (lo + hi)
    return s if log_lik(s) >= values[best] else scan[best]


def wander(cracks: Tensor, since_m: Tensor, path_sd: float, seed: int = 0) -> Tensor:
    """cracks (samples, tails) with each sample's log moved by N(0, path_sd**2 d), d = ln(a /
    since_m) (tails,) the log growth since the tail's latest measurement (module docstring);
    unchanged where path_sd is 0."""
    if path_sd <= 0:
        return cracks
    generator = torch.Generator().manual_seed(seed)
    noise = torch.randn(cracks.shape, generator=generator, dtype=torch.float64)
    growth = torch.log(cracks.clamp_min(1e-12) / since_m[None, :]).clamp_min(0.0)
    return cracks * torch.exp(path_sd * growth.sqrt() * noise)
