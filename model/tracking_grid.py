"""The exact per-tail posterior over z on a grid: each tail's histories marched under grid
values, and the likelihood of its inspections under them.

Apart from model.tracking (the hierarchical model, the fleet prior, the evidence and the
posterior's type), because this is the part that marches: the model's compiled march run once
per grid value of every inspected tail, and the inspections' likelihood read off its cracks.
model.tracking_fit reuses these grids for the fleet prior and the joint fit.

Posterior.  z is one number per tail, so its posterior is computed exactly on a grid: the tail's
histories (every segment, repairs included) are marched under each grid value, all grid values
of a batch of tails as lanes of one compiled march.  The grid is the union of three passes: a
coarse one over [-2, 2], a fine one around the likelihood's peak and a fine one around the
posterior's, so it resolves posteriors narrower than the coarse spacing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import Tensor

from model.hybrid import CrackGrowthModel
from model.integrate import Observations
from model.physics import ParisLaw
from model.tracking import GrowthPosterior, SizingError, TailEvidence, TrackingPrior
from model.train import non_detection_nll

COARSE_GRID = torch.linspace(-2.0, 2.0, 21, dtype=torch.float64)
FINE_POINTS = 25
FINE_HALF_WIDTH_SD = 6.0
# lanes (tail segments x grid values) marched together: bounds memory at ~lanes x flights x 16 B.
# Few enough that the march's per-lane buffers stay in cache: per lane and flight the residual
# kernel's march took 34 ns at 2,048 lanes, 26.5 at 1,024, 21 at 512 and 19 at 320 (5,840
# flights, the 2-core machine; each lane's march is its own, so the bits do not change)
_LANES_PER_MARCH = 320


def predict_on_grid(model: CrackGrowthModel, evidence: TailEvidence, z: Tensor) -> Tensor:
    """Predicted crack (observations, points) at each observation under each of its tail's grid
    values z (tails, points): every row marched with growth factor exp(z), as lanes, up to its
    chunk's last observation."""
    loads, obs = evidence.loads, evidence.observations
    points = z.shape[1]
    out = torch.empty(len(obs.aircraft), points, dtype=torch.float64)
    rows_per_march = max(1, _LANES_PER_MARCH // points)
    initial = loads.initial_or(model.spec.law.initial_crack_m)
    used = torch.unique(obs.aircraft)
    for start in range(0, len(used), rows_per_march):
        rows = used[start : start + rows_per_march]
        local = torch.full((len(loads.lengths),), -1, dtype=torch.long)
        local[rows] = torch.arange(len(rows))
        mine = torch.nonzero(local[obs.aircraft] >= 0).squeeze(1)
        part = model.loads_for(loads.select(rows).until(int(obs.flights[mine].max())))
        lanes = len(rows) * points
        stress = part.stress_range_mpa.to(torch.float64).repeat_interleave(points, dim=0)
        factor = torch.exp(z[evidence.row_tail[rows]]).reshape(lanes)
        lane = local[obs.aircraft[mine]][:, None] * points + torch.arange(points)[None, :]
        flights = obs.flights[mine][:, None].expand_as(lane)
        with torch.no_grad():
            crack = model(
                stress,
                part.lengths.repeat_interleave(points),
                initial[rows].repeat_interleave(points),
                factor,
                at=(lane.reshape(-1), flights.reshape(-1)),
            )
        out[mine] = crack.view(lane.shape)
    return out


def observation_log_likelihood(
    predicted: Tensor,
    observations: Observations,
    sizing: SizingError,
    law: ParisLaw | None = None,
) -> Tensor:
    """log p(observation | predicted crack) (observations, points): measured cracks under the
    log-normal sizing error, non-detections through the PoD curve seen through it.

    law: where given (a tail's posterior, Grid), a measured crack at or past
    law.runaway_crack_m says only that the crack reached a_crit (right-censored, as a no-find
    is left-censored): log P(measured >= a_crit | a) = log Phi((ln a - ln a_crit) / s(a)).
    Read as a size, the fleet generator's torn-through 0.5 m pushed its tail's factor on past
    where its crack fails and the fleet's spread up (benchmarks/RESULTS.md, session 17).  The
    fits of the shared model and of C and m leave such cracks out and pass none."""
    a = predicted.clamp_min(1e-12)
    sd = sizing.log_sd(a)
    hit = observations.measured
    out = torch.empty_like(a)
    y_all = observations.crack_length_m.to(torch.float64)
    if law is not None:
        failed = hit & (y_all >= law.runaway_crack_m)
        hit = hit & ~failed
        if bool(failed.any()):
            over = (torch.log(a[failed]) - math.log(law.critical_crack_m)) / sd[failed]
            out[failed] = torch.special.log_ndtr(over)
    y = y_all[hit, None]
    r = (torch.log(y) - torch.log(a[hit])) / sd[hit]
    out[hit] = -0.5 * r**2 - torch.log(sd[hit]) - 0.5 * math.log(2 * math.pi)
    missed = ~observations.measured
    if bool(missed.any()):
        assert observations.detection_a50_m is not None
        a50 = observations.detection_a50_m[missed].double()[:, None].expand_as(a[missed])
        a90 = observations.detection_a90_m
        a90 = None if a90 is None else a90[missed].double()[:, None].expand_as(a[missed])
        out[missed] = -non_detection_nll(a[missed], a50, a90, sd[missed])
    return out


def trapezoid_weights(z: Tensor) -> Tensor:
    """Trapezoid quadrature weights (tails, points) of sorted grids z."""
    gaps = z.diff(dim=1)
    pad = torch.zeros(z.shape[0], 1, dtype=z.dtype)
    return 0.5 * (torch.cat((pad, gaps), dim=1) + torch.cat((gaps, pad), dim=1))


@dataclass(frozen=True)
class Grid:
    """Per-tail grid z (tails, points), sorted, and the predictions at each observation."""

    z: Tensor
    predicted: Tensor  # (observations, points), each row on its own tail's grid
    law: ParisLaw  # the marching model's: where a measured crack says only "failed"

    def log_likelihood(self, evidence: TailEvidence, sizing: SizingError) -> Tensor:
        """Per-tail log-likelihood (tails, points)."""
        terms = observation_log_likelihood(self.predicted, evidence.observations, sizing, self.law)
        out = torch.zeros_like(self.z)
        return out.index_add_(0, evidence.observation_tail, terms)

    def extend(self, model: CrackGrowthModel, evidence: TailEvidence, z_new: Tensor) -> Grid:
        """The union with z_new (tails, k), re-sorted, predictions marched for the new points."""
        z = torch.cat((self.z, z_new), dim=1)
        predicted = torch.cat((self.predicted, predict_on_grid(model, evidence, z_new)), dim=1)
        order = torch.argsort(z, dim=1)
        obs_order = order[evidence.observation_tail]
        return Grid(z.gather(1, order), predicted.gather(1, obs_order), self.law)


def _moments(z: Tensor, log_density: Tensor) -> tuple[Tensor, Tensor]:
    """Mean and sd (tails,) of densities exp(log_density) on grids z."""
    mass = _normalised_mass(z, log_density)
    mean = (mass * z).sum(dim=1)
    sd = (mass * (z - mean[:, None]) ** 2).sum(dim=1).sqrt()
    return mean, sd


def _normalised_mass(z: Tensor, log_density: Tensor) -> Tensor:
    logw = log_density + torch.log(trapezoid_weights(z).clamp_min(1e-300))
    logw = logw - logw.max(dim=1, keepdim=True).values
    w = torch.exp(logw)
    return w / w.sum(dim=1, keepdim=True)


def _fine(centre: Tensor, sd: Tensor) -> Tensor:
    """FINE_POINTS grid values (tails, FINE_POINTS) over centre +- FINE_HALF_WIDTH_SD sd."""
    span = torch.linspace(-FINE_HALF_WIDTH_SD, FINE_HALF_WIDTH_SD, FINE_POINTS, dtype=torch.float64)
    width = sd.clamp(1e-3, 0.5)[:, None]
    return (centre[:, None] + width * span[None, :]).clamp(-3.0, 3.0)


def build_grid(model: CrackGrowthModel, evidence: TailEvidence, sizing: SizingError) -> Grid:
    """Coarse grid plus a fine grid around each tail's likelihood peak (flat prior)."""
    coarse = COARSE_GRID.expand(evidence.tails, -1).contiguous()
    grid = Grid(coarse, predict_on_grid(model, evidence, coarse), model.spec.law)
    mean, sd = _moments(grid.z, grid.log_likelihood(evidence, sizing))
    spacing = float(COARSE_GRID[1] - COARSE_GRID[0])
    return grid.extend(model, evidence, _fine(mean, torch.maximum(sd, torch.tensor(spacing / 4))))


def growth_posterior(
    model: CrackGrowthModel,
    evidence: TailEvidence,
    prior: TrackingPrior,
    grid: Grid | None = None,
) -> GrowthPosterior:
    """Each tail's posterior over z given its own inspections and its prior
    (TrackingPrior.tail_priors: the fleet's, and a small chance of being unlike it, under each
    sizing node); the model's fitted weights march.  grid: fit_prior's, to reuse its marches.
    A tail without inspections holds the fleet's posterior predictive (fleet_grid)."""
    if grid is None:
        grid = build_grid(model, evidence, prior.sizing)
    mean, sd = _moments(grid.z, _log_posterior(grid, evidence, prior))
    grid = grid.extend(model, evidence, _fine(mean, sd))
    z, mass = grid.z.clone(), _normalised_mass(grid.z, _log_posterior(grid, evidence, prior))
    uninformed = ~evidence.informed
    if bool(uninformed.any()):
        prior_z, prior_log = prior.fleet_grid(z.shape[1])
        z[uninformed] = prior_z
        mass[uninformed] = _normalised_mass(prior_z[None, :], prior_log[None, :])
    return GrowthPosterior(z, mass)


def _log_posterior(grid: Grid, evidence: TailEvidence, prior: TrackingPrior) -> Tensor:
    """(tails, points) log of each tail's posterior density on its grid, up to a constant a
    tail: the mixture over the prior's sizing nodes of the tail's posterior under each, each
    normalised on the grid and weighted by its node's weight."""
    posteriors = [
        (weight, grid.log_likelihood(evidence, sizing) + prior.log_density(grid.z, spread))
        for weight, sizing, spread in prior.tail_priors()
    ]
    if len(posteriors) == 1:
        return posteriors[0][1]
    width = torch.log(trapezoid_weights(grid.z).clamp_min(1e-300))
    parts = [
        log_post
        - torch.logsumexp(log_post + width, dim=1, keepdim=True)
        + math.log(max(weight, 1e-300))
        for weight, log_post in posteriors
    ]
    return torch.logsumexp(torch.stack(parts), dim=0)
