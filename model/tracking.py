"""Individual aircraft tracking: each tail's own growth rate, learned from its own inspections.

Hierarchical model.  Tail i grows at f_i = exp(z_i) times the fleet model's rate
(model.cells.DamageCell's growth factor), with the fleet prior z_i ~ N(0, tau**2): replicate
specimens of one alloy under one load differ by tens of percent in growth rate (Virkler 1979,
Hudak 1978).  An inspection of crack a measures ln y = ln a + e, e ~ N(0, s(a)**2), with the
sizing error s(a)**2 = s_rel**2 + (s_abs / a)**2 (`SizingError`: a relative and an absolute part);
a non-detection has P(not detected | a) = Phi((ln a50 - ln a) / sqrt(s_pod**2 + s(a)**2))
(model.train.non_detection_nll with the sizing sd).

Posterior.  z is one number per tail, so its posterior is computed exactly on a grid: the tail's
histories (every segment, repairs included) are marched under each grid value, all grid values
of a batch of tails as lanes of one compiled march.  The grid is the union of three passes: a
coarse one over [-2, 2], a fine one around the likelihood's peak and a fine one around the
posterior's, so it resolves posteriors narrower than the coarse spacing.  Sampling and quantiles
use the piecewise-linear CDF of the trapezoid masses.

Fleet prior (empirical Bayes, model.tracking_fit).  z_i ~ N(mu, tau**2): mu, the fleet's own
rate against the model's, and tau maximise the marginal likelihood of the inspected tails,
prod_i int L_i(z) N(z; mu, tau**2) dz, on the same grids; in a fleet without scatter tau goes to
~0 and every tail keeps the fleet's rate exp(mu).  With a mean of 0 (as before) a fleet whose
physics is off by a constant put that constant into its inspected tails' factors, and every
uninspected tail inherited the physics' bias (a flat geometry factor of 1.08: their cracks 27 %
short).  A tail's own measurements always count: its prior is the fleet's with tau at least
TAU_FLOOR, mixed with a small share (SURPRISE_SHARE) of a wide one (SURPRISE_SD), so a
measurement many sizing errors from its tail's forecast moves that tail (its factor, and so its
crack) where the fleet's spread alone would have held it at the fleet's rate.  A tail never
inspected takes the fleet's N(mu, tau**2) with the same floor: fifteen exactly measured tails
read tau ~1e-9, but the shared model fitted to them errs on the others' load mixes by more than
that (scenario II with Paris' law as its truth: 0.15-0.2 % against bands 0.05 % wide, which
held 19-21 % of the uninspected tails; with the floor 100 % at 3.3 % wide,
benchmarks/RESULTS.md).  Where the fleet scatters, a tail never inspected is drawn with the
fleet spread's upper 95 % confidence limit (the profile of the evidence, model.fleet_spread), not
its estimate, as a B-basis allowable bounds a population from a sample: on 100 inspected tails
whose realised spread was 0.23 the estimate read 0.21, and the uninspected tails (their own
spread 0.26) were held 80-83 % by bands meant to hold 90 %.  The relative sizing sd is
estimated too where enough tails have repeated measurements (the within-tail residuals at each
tail's best z see only the sizing error), else the setting stands.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import torch
from torch import Tensor

from model.hybrid import CrackGrowthModel
from model.integrate import LoadHistory, Observations
from model.physics import ParisLaw
from model.train import non_detection_nll

COARSE_GRID = torch.linspace(-2.0, 2.0, 21, dtype=torch.float64)
FINE_POINTS = 25
FINE_HALF_WIDTH_SD = 6.0
MAX_GROWTH_SD = 1.5
# Below this fleet spread of ln growth rate a fleet is read as without scatter (the thesis's
# world): every tail keeps the fleet's rate, the shared model is not refitted per tail, and
# forecasts sample the weights' posterior as before tracking existed.
MIN_GROWTH_SD = 0.02
# A tail's prior on z (TrackingPrior.log_density, and fleet_grid's for a tail never inspected):
# the fleet's, its sd at least TAU_FLOOR (a fleet never reads as exactly alike), mixed with
# SURPRISE_SHARE of N(mu, SURPRISE_SD**2): the chance that a tail is not like the fleet at all
# (a different repair, a mis-recorded load), which lets a surprising measurement move its tail
# (the demo's: 11.6 sizing sds over its forecast moved nothing with tau 2.7e-9).
TAU_FLOOR = 0.01
SURPRISE_SHARE = 0.01
SURPRISE_SD = 0.5
# lanes (tail segments x grid values) marched together: bounds memory at ~lanes x flights x 16 B.
# Few enough that the march's per-lane buffers stay in cache: per lane and flight the residual
# kernel's march took 34 ns at 2,048 lanes, 26.5 at 1,024, 21 at 512 and 19 at 320 (5,840
# flights, the 2-core machine; each lane's march is its own, so the bits do not change)
_LANES_PER_MARCH = 320


@dataclass(frozen=True)
class SizingError:
    """Inspection sizing error: sd of ln(measured / true) = sqrt(relative_sd**2 + (absolute_sd_m / a)**2)."""

    relative_sd: float = 0.05
    absolute_sd_m: float = 0.0001

    def __post_init__(self) -> None:
        if not self.relative_sd > 0:
            raise ValueError(f"relative_sd must be > 0, got {self.relative_sd}")
        if not self.absolute_sd_m >= 0:
            raise ValueError(f"absolute_sd_m must be >= 0, got {self.absolute_sd_m}")

    def log_sd(self, crack_length_m: Tensor) -> Tensor:
        """sd of ln(measured) for true cracks crack_length_m (any shape), m."""
        relative = self.absolute_sd_m / crack_length_m.clamp_min(1e-12)
        return torch.sqrt(self.relative_sd**2 + relative**2)


@dataclass(frozen=True)
class TrackingPrior:
    """The fleet-level part of tracking: growth_mean = mu and growth_sd = tau, the mean and sd of
    ln growth factor across tails (the fleet's rate against the shared model's, and its
    spread), and the inspections' sizing error; `estimated` says which were learned from the data.
    path_sd: how far forecasts drift from later measurements beyond the posterior, its spread
    growing as the square of the log growth extrapolated (model.path_variability; 0: none)."""

    growth_sd: float
    sizing: SizingError
    estimated: tuple[str, ...] = ()
    path_sd: float = 0.0
    growth_mean: float = 0.0
    growth_sd_upper: float | None = None

    def __post_init__(self) -> None:
        if not 0 <= self.growth_sd <= MAX_GROWTH_SD:
            raise ValueError(f"growth_sd must lie in [0, {MAX_GROWTH_SD}], got {self.growth_sd}")
        if self.growth_sd_upper is not None and not (
            self.growth_sd <= self.growth_sd_upper <= MAX_GROWTH_SD
        ):
            raise ValueError(
                f"growth_sd_upper must lie in [growth_sd, {MAX_GROWTH_SD}], "
                f"got {self.growth_sd_upper}"
            )

    @property
    def scatters(self) -> bool:
        """Whether tails differ in growth rate (growth_sd above MIN_GROWTH_SD): then each tail's
        growth posterior carries its forecast's uncertainty."""
        return self.growth_sd > MIN_GROWTH_SD

    def log_density(self, z: Tensor) -> Tensor:
        """A tail's prior log density of z (any shape): surprise_prior about mu, tau floored at
        TAU_FLOOR."""
        return surprise_prior(z - self.growth_mean, max(self.growth_sd, TAU_FLOOR))[0]

    @property
    def uninspected_sd(self) -> float:
        """The spread a tail never inspected is drawn with (module docstring): where the fleet
        scatters, its spread's upper confidence limit; else its spread; at least TAU_FLOOR."""
        upper = self.growth_sd_upper if self.scatters else None
        return max(self.growth_sd if upper is None else upper, TAU_FLOOR)

    def fleet_grid(self, points: int) -> tuple[Tensor, Tensor]:
        """z (points,) and its log density under N(mu, uninspected_sd**2): the posterior of a
        tail that was never inspected."""
        sd = self.uninspected_sd
        z = self.growth_mean + torch.linspace(-6, 6, points, dtype=torch.float64) * sd
        return z, log_normal_pdf(z - self.growth_mean, sd)

    def to_dict(self) -> dict[str, Any]:
        return {
            "growth_sd": self.growth_sd,
            "sizing_relative_sd": self.sizing.relative_sd,
            "sizing_absolute_sd_m": self.sizing.absolute_sd_m,
            "estimated": list(self.estimated),
            "path_sd": self.path_sd,
            "growth_mean": self.growth_mean,
            "growth_sd_upper": self.growth_sd_upper,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TrackingPrior:
        """Inverse of to_dict; raises ValueError for anything else."""
        try:
            sizing = SizingError(
                float(data["sizing_relative_sd"]), float(data["sizing_absolute_sd_m"])
            )
            return cls(
                float(data["growth_sd"]),
                sizing,
                tuple(data.get("estimated", ())),
                float(data.get("path_sd", 0.0)),  # files written before path variability
                float(data.get("growth_mean", 0.0)),  # files written before the fleet mean
                _optional_float(data.get("growth_sd_upper")),  # and before its upper limit
            )
        except (KeyError, TypeError) as exc:
            raise ValueError(f"not a tracking prior: {exc!r}") from exc


def _optional_float(value: Any) -> float | None:
    return None if value is None else float(value)


def surprise_prior(deviation: Tensor, sd: float) -> tuple[Tensor, Tensor]:
    """log density and curvature (-d2/dz2) of N(0, sd**2) mixed with SURPRISE_SHARE of
    N(0, SURPRISE_SD**2) at deviation = z - mu (any shape): the fleet's prior of a tail that
    may be unlike it (module docstring).  The fit of the shared model and the fleet's spread
    read it too, so one surprising tail moves its own factor, not the kernel or the spread."""
    fleet = log_normal_pdf(deviation, sd) + math.log1p(-SURPRISE_SHARE)
    wide = log_normal_pdf(deviation, SURPRISE_SD) + math.log(SURPRISE_SHARE)
    log_density = torch.logaddexp(fleet, wide)
    narrow = torch.exp(fleet - log_density)  # the fleet component's share at each deviation
    precisions = (sd**-2, SURPRISE_SD**-2)
    slopes = (deviation * precisions[0], deviation * precisions[1])
    mean_slope = narrow * slopes[0] + (1 - narrow) * slopes[1]
    # -d2/dz2 log of a mixture: the shares' precisions less the slopes' variance across them
    spread = narrow * slopes[0] ** 2 + (1 - narrow) * slopes[1] ** 2 - mean_slope**2
    curvature = narrow * precisions[0] + (1 - narrow) * precisions[1] - spread
    return log_density, curvature


@dataclass(frozen=True)
class TailEvidence:
    """What tracking conditions on, for a batch of tails.

    loads: one row per history segment (a tail repaired once has two), with its initial crack;
    row_tail: (rows,) the tail (0..tails-1) of each row; observations: index rows of loads;
    tails: how many tails (tails without a row or observation get the fleet prior).
    """

    loads: LoadHistory
    row_tail: Tensor
    observations: Observations
    tails: int

    def __post_init__(self) -> None:
        if self.row_tail.shape != self.loads.lengths.shape:
            raise ValueError("row_tail must give one tail per row of loads")
        if len(self.row_tail) and not 0 <= int(self.row_tail.min()) <= int(
            self.row_tail.max()
        ) < max(self.tails, 1):
            raise ValueError(f"row_tail must lie in [0, {self.tails})")

    @property
    def observation_tail(self) -> Tensor:  # (observations,)
        return self.row_tail[self.observations.aircraft]

    @property
    def informed(self) -> Tensor:  # (tails,) bool: the tail has an inspection
        out = torch.zeros(self.tails, dtype=torch.bool)
        out[self.observation_tail] = True
        return out


@dataclass(frozen=True)
class GrowthPosterior:
    """Each tail's posterior over z = ln growth factor, on a per-tail grid.

    z: (tails, points) sorted grid; mass: (tails, points) probability of each point (trapezoid
    masses, rows sum to 1).  A tail without inspections holds the prior N(0, growth_sd**2).
    """

    z: Tensor
    mass: Tensor

    @property
    def tails(self) -> int:
        return int(self.z.shape[0])

    def _cdf(self) -> Tensor:
        """CDF at the grid points, each point's mass centred on it (midpoint rule)."""
        return (self.mass.cumsum(dim=1) - 0.5 * self.mass).clamp(0.0, 1.0)

    def quantiles(self, probabilities: Sequence[float]) -> Tensor:
        """z quantiles (tails, len(probabilities)) by linear interpolation of the CDF."""
        u = torch.tensor(list(probabilities), dtype=torch.float64)
        return _interp_rows(u.expand(self.tails, -1), self._cdf(), self.z)

    def factor_quantiles(self, probabilities: Sequence[float]) -> Tensor:
        """Growth factor exp(z) quantiles (tails, len(probabilities))."""
        return torch.exp(self.quantiles(probabilities))

    def mean(self) -> Tensor:  # (tails,)
        return (self.mass * self.z).sum(dim=1)

    def sample(self, count: int, seed: int = 0) -> Tensor:
        """count draws (count, tails) of z: stratified uniforms, shuffled per tail by seed, so
        that a few hundred samples already give stable quantiles."""
        if count < 1:
            raise ValueError(f"count must be >= 1, got {count}")
        gen = torch.Generator().manual_seed(seed)
        strata = (torch.arange(count, dtype=torch.float64) + 0.5) / count
        order = torch.argsort(torch.rand(self.tails, count, generator=gen), dim=1)
        u = strata[order]  # (tails, count)
        return _interp_rows(u, self._cdf(), self.z).T.contiguous()

    def select(self, tails: Tensor) -> GrowthPosterior:
        return GrowthPosterior(self.z[tails], self.mass[tails])


def _interp_rows(u: Tensor, cdf: Tensor, z: Tensor) -> Tensor:
    """Per row, the z where the piecewise-linear CDF reaches u: (rows, k) from (rows, points)."""
    index = torch.searchsorted(cdf.contiguous(), u.contiguous()).clamp(1, z.shape[1] - 1)
    lo_c, hi_c = cdf.gather(1, index - 1), cdf.gather(1, index)
    lo_z, hi_z = z.gather(1, index - 1), z.gather(1, index)
    t = ((u - lo_c) / (hi_c - lo_c).clamp_min(1e-300)).clamp(0.0, 1.0)
    return lo_z + t * (hi_z - lo_z)


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


def log_normal_pdf(z: Tensor, sd: float) -> Tensor:
    if sd <= 0:
        return torch.where(z == 0, 0.0, -math.inf).to(z.dtype)
    return -0.5 * (z / sd) ** 2 - math.log(sd * math.sqrt(2 * math.pi))


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
    (TrackingPrior.log_density: the fleet's, and a small chance of being unlike it); the
    model's fitted weights march.  grid: fit_prior's, to reuse its marches.  A tail without
    inspections holds the fleet's N(mu, tau**2)."""
    if grid is None:
        grid = build_grid(model, evidence, prior.sizing)
    ll = grid.log_likelihood(evidence, prior.sizing)
    mean, sd = _moments(grid.z, ll + prior.log_density(grid.z))
    grid = grid.extend(model, evidence, _fine(mean, sd))
    log_post = grid.log_likelihood(evidence, prior.sizing) + prior.log_density(grid.z)
    z, mass = grid.z.clone(), _normalised_mass(grid.z, log_post)
    uninformed = ~evidence.informed
    if bool(uninformed.any()):
        prior_z, prior_log = prior.fleet_grid(z.shape[1])
        z[uninformed] = prior_z
        mass[uninformed] = _normalised_mass(prior_z[None, :], prior_log[None, :])
    return GrowthPosterior(z, mass)
