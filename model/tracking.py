"""Individual aircraft tracking: each tail's own growth rate, learned from its own inspections.

Hierarchical model.  Tail i grows at f_i = exp(z_i) times the fleet model's rate
(model.cells.DamageCell's growth factor), with the fleet prior z_i ~ N(0, tau**2): replicate
specimens of one alloy under one load differ by tens of percent in growth rate (Virkler 1979,
Hudak 1978).  An inspection of crack a measures ln y = ln a + e, e ~ N(0, s(a)**2), with the
sizing error s(a)**2 = s_rel**2 + (s_abs / a)**2 (`SizingError`: a relative and an absolute part);
a non-detection has P(not detected | a) = Phi((ln a50 - ln a) / sqrt(s_pod**2 + s(a)**2))
(model.train.non_detection_nll with the sizing sd).

Posterior.  Exact, on a per-tail grid over z (model.tracking_grid); GrowthPosterior holds it,
sampling and quantiles by the piecewise-linear CDF of its trapezoid masses.

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
benchmarks/RESULTS.md).  Where the spread is estimated, a tail never inspected draws its
factor from its posterior predictive given the inspected tails (model.fleet_spread
.spread_posterior): a mixture of N(mu, tau_k**2 + var(mu | tau_k)) over the spread's
posterior, the profile of the evidence times a half-normal prior of sd 0.3.  It is as wide as
the spread is uncertain: 100 tails measured well pin it, one round at year 1 barely does, and
the estimate alone (read 0 there) held such tails at the fleet's rate; an upper confidence
limit, its predecessor, was one number for both.  An inspected tail's prior is the same
posterior of the spread (`SizingNode.spread`), not the estimate of tau: a few tails inspected
once tell the spread poorly, and held at its estimate their own factors were shrunk as if it
were known.

The relative sizing sd is estimated where enough tails have repeated measurements (the
within-tail residuals at each tail's best z see only the sizing error).  Where none are, the
data cannot tell the sizing error from the fleet's spread (one crack a tail shows only their
sum), so it is integrated over its prior about the method's stated value (SIZING_PRIOR_SD,
SIZING_NODES), each node weighted by the inspected tails' evidence under it, and every tail's
posterior is the mixture of its posteriors under the nodes (model.tracking_grid).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import torch
from torch import Tensor

from model.integrate import LoadHistory, Observations

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
# An inspection method's stated sizing error is known to about a factor of two either way:
# ln s_rel ~ N(ln s_method, SIZING_PRIOR_SD**2) where no repeated measurement measures it,
# integrated by SIZING_NODES Gauss-Hermite nodes (module docstring)
SIZING_PRIOR_SD = math.log(2.0)
SIZING_NODES = 5


@dataclass(frozen=True)
class SizingNode:
    """One relative sizing sd of the integration over it (module docstring): its posterior
    weight, and the fleet spread's posterior under it ((sd, weight) pairs, as
    TrackingPrior.uninspected_spread)."""

    relative_sd: float
    weight: float
    spread: tuple[tuple[float, float], ...]

    def to_list(self) -> list[Any]:
        return [self.relative_sd, self.weight, [list(pair) for pair in self.spread]]

    @classmethod
    def from_list(cls, data: Sequence[Any]) -> SizingNode:
        sd, weight, spread = data
        return cls(float(sd), float(weight), tuple((float(t), float(w)) for t, w in spread))


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
    uninspected_spread: tuple[tuple[float, float], ...] = ()
    sizing_nodes: tuple[SizingNode, ...] = ()

    def __post_init__(self) -> None:
        if not 0 <= self.growth_sd <= MAX_GROWTH_SD:
            raise ValueError(f"growth_sd must lie in [0, {MAX_GROWTH_SD}], got {self.growth_sd}")
        spread = self.uninspected_spread
        if spread and not (
            all(0 < sd <= 2 * MAX_GROWTH_SD and weight >= 0 for sd, weight in spread)
            and abs(sum(weight for _, weight in spread) - 1) < 1e-6
        ):
            raise ValueError(
                f"uninspected_spread must be (sd, weight) pairs with sd in (0, "
                f"{2 * MAX_GROWTH_SD}] and weights summing to 1, got {spread}"
            )
        nodes = self.sizing_nodes
        if nodes and not (
            all(node.relative_sd > 0 and node.weight >= 0 and node.spread for node in nodes)
            and abs(sum(node.weight for node in nodes) - 1) < 1e-6
        ):
            raise ValueError("sizing_nodes must have sd > 0, a spread and weights summing to 1")

    @property
    def scatters(self) -> bool:
        """Whether tails differ in growth rate (growth_sd above MIN_GROWTH_SD): then each tail's
        growth posterior carries its forecast's uncertainty."""
        return self.growth_sd > MIN_GROWTH_SD

    def tail_priors(self) -> tuple[tuple[float, SizingError, tuple[tuple[float, float], ...]], ...]:
        """(weight, sizing error, spread) of each prior an inspected tail's posterior mixes
        (module docstring): one per sizing node where the spread's posterior was read, else
        one, the sizing error and tau (floored at TAU_FLOOR)."""
        if self.sizing_nodes:
            return tuple(
                (node.weight, replace(self.sizing, relative_sd=node.relative_sd), node.spread)
                for node in self.sizing_nodes
            )
        return ((1.0, self.sizing, self._point_spread()),)

    def _point_spread(self) -> tuple[tuple[float, float], ...]:
        """N(mu, tau**2) as a spread of one, tau floored at TAU_FLOOR."""
        return ((max(self.growth_sd, TAU_FLOOR), 1.0),)

    def log_density(
        self, z: Tensor, spread: tuple[tuple[float, float], ...] | None = None
    ) -> Tensor:
        """A tail's prior log density of z (any shape) under one of tail_priors' spreads (by
        default N(mu, tau**2), tau floored at TAU_FLOOR): the mixture of N(mu, sd_k**2) with
        its surprise share (with_surprise)."""
        deviation = z - self.growth_mean
        parts = [
            log_normal_pdf(deviation, sd) + math.log(weight)
            for sd, weight in spread or self._point_spread()
            if weight > 0
        ]
        return with_surprise(deviation, torch.logsumexp(torch.stack(parts), dim=0))[2]

    def fleet_grid(self, points: int) -> tuple[Tensor, Tensor]:
        """z (points,) and its log density for a tail never inspected: the mixture of
        N(mu, tau_k**2) over the spread's posterior (uninspected_spread; module docstring),
        else N(mu, tau**2); each sd at least TAU_FLOOR.  The points are dense where the
        narrowest likely spread puts its mass and sparse in the widest one's tails:
        z = mu + c sinh(t), t uniform."""
        spread = self.uninspected_spread or ((self.growth_sd, 1.0),)
        taus = torch.tensor([max(sd, TAU_FLOOR) for sd, _ in spread], dtype=torch.float64)
        weights = torch.tensor([weight for _, weight in spread], dtype=torch.float64)
        likely = taus[weights >= 1e-4 * weights.max()]
        narrow, wide = float(likely.min()), float(likely.max())
        reach = math.asinh(6 * wide / narrow)
        t = torch.linspace(-reach, reach, points, dtype=torch.float64)
        deviation = narrow * torch.sinh(t)
        components = torch.stack([log_normal_pdf(deviation, float(tau)) for tau in taus])
        log_density = torch.logsumexp(components + torch.log(weights)[:, None], dim=0)
        return self.growth_mean + deviation, log_density

    def to_dict(self) -> dict[str, Any]:
        return {
            "growth_sd": self.growth_sd,
            "sizing_relative_sd": self.sizing.relative_sd,
            "sizing_absolute_sd_m": self.sizing.absolute_sd_m,
            "estimated": list(self.estimated),
            "path_sd": self.path_sd,
            "growth_mean": self.growth_mean,
            "uninspected_spread": [list(pair) for pair in self.uninspected_spread],
            "sizing_nodes": [node.to_list() for node in self.sizing_nodes],
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
                _uninspected_spread(data),
                tuple(SizingNode.from_list(node) for node in data.get("sizing_nodes", ())),
            )
        except (KeyError, TypeError) as exc:
            raise ValueError(f"not a tracking prior: {exc!r}") from exc


def _uninspected_spread(data: dict[str, Any]) -> tuple[tuple[float, float], ...]:
    """The stored spread posterior; a file of an earlier release drew tails never inspected at
    the spread's upper limit where the fleet scattered, and keeps doing so."""
    if "uninspected_spread" in data:
        return tuple((float(tau), float(weight)) for tau, weight in data["uninspected_spread"])
    upper = data.get("growth_sd_upper")
    if upper is not None and float(data["growth_sd"]) > MIN_GROWTH_SD:
        return ((float(upper), 1.0),)
    return ()


def surprise_prior(deviation: Tensor, sd: float) -> tuple[Tensor, Tensor]:
    """log density and curvature (-d2/dz2) of N(0, sd**2) mixed with SURPRISE_SHARE of
    N(0, SURPRISE_SD**2) at deviation = z - mu (any shape): the fleet's prior of a tail that
    may be unlike it (module docstring).  The fit of the shared model and the fleet's spread
    read it too, so one surprising tail moves its own factor, not the kernel or the spread."""
    fleet, _, log_density = with_surprise(deviation, log_normal_pdf(deviation, sd))
    narrow = torch.exp(fleet - log_density)  # the fleet component's share at each deviation
    precisions = (sd**-2, SURPRISE_SD**-2)
    slopes = (deviation * precisions[0], deviation * precisions[1])
    mean_slope = narrow * slopes[0] + (1 - narrow) * slopes[1]
    # -d2/dz2 log of a mixture: the shares' precisions less the slopes' variance across them
    spread = narrow * slopes[0] ** 2 + (1 - narrow) * slopes[1] ** 2 - mean_slope**2
    curvature = narrow * precisions[0] + (1 - narrow) * precisions[1] - spread
    return log_density, curvature


def surprise_log_density(deviation: Tensor, sd: float) -> Tensor:
    """surprise_prior's log density alone: the evidence's integrals read it thousands of times
    a fit (model.fleet_spread), and need no curvature."""
    return with_surprise(deviation, log_normal_pdf(deviation, sd))[2]


def with_surprise(deviation: Tensor, fleet_log_density: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """The fleet's log density at deviation = z - mu mixed with SURPRISE_SHARE of
    N(0, SURPRISE_SD**2) (module docstring): the fleet's and the wide share's weighted log
    densities, and the mixture's."""
    fleet = fleet_log_density + math.log1p(-SURPRISE_SHARE)
    wide = log_normal_pdf(deviation, SURPRISE_SD) + math.log(SURPRISE_SHARE)
    return fleet, wide, torch.logaddexp(fleet, wide)


def log_normal_pdf(z: Tensor, sd: float) -> Tensor:
    if sd <= 0:
        return torch.where(z == 0, 0.0, -math.inf).to(z.dtype)
    return -0.5 * (z / sd) ** 2 - math.log(sd * math.sqrt(2 * math.pi))


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
