"""Model-form uncertainty beyond the measured cracks: the geometry factor's unknown trend.

Why.  Inspections pin the kernel's correction to the physics only over the crack sizes they
measured; the tails that matter most (about to reach a_crit) are always beyond them.  There the
correction is held at the edge of its input box (model.cells.ResidualKernel), and nothing said
how wrong that may be: a fleet whose true geometry factor accelerates towards a panel's edge
(F = sqrt(sec(pi a / 2W))) was forecast with bands that held 65 % of the year-5 cracks and
P(critical) = 0 for tails that failed within the year.

Model.  Beyond a_s, the longest crack measured, the geometry factor is the edge's times level
(a / a_s)**eta, eta ~ N(slope, slope_sd**2) drawn once per sample and shared by every tail of it
(one structure, one unknown trend): the log geometry factor's slope in ln a is not known there,
and its spread grows with ln(a / a_s), the distance extrapolated.  `slope` is the trend the
fitted correction shows over the last doubling of the measured cracks (for the physics alone a
prior mean, untold_trend: a constant F's part rises towards its edges); `slope_sd` is a prior
(the physics' plausible range), since no inspection below a_s can say more.  `level` (>= 1) lifts
the edge's correction to its highest over the measured cracks: a fall over them gets no credit
beyond them, as a falling trend gets none (MAX_TREND_SLOPE's floor).  Where tails scatter and the
first inspections barely pin each tail's factor, a fit can trade the correction's shape against
the fleet's spread and learn a fall the truth lacks (a secant fleet inspected at years 1 and 3:
0.985 at 8 mm to 0.92 at 18 mm, the truth rising; held at 0.92 beyond, five tails reaching
a_crit within the year read P(critical) < 0.05, two with the level).

Exact, and outside the march.  Beyond a_s the growth rate separates, da/dN = D_t h(a) with
D_t = f C (dS_t (1 + MLP(dS_t, a_s)))**m of the flight alone and h(a) = (F sqrt(pi a))**m: the
correction is held there, so the crack is a function of the damage accumulated since a_s.  Under
eta that function changes by the closed form below, so a trajectory marched with the held
correction maps onto the one under eta crack by crack (`beyond`), and back (`within`): sampled
trajectories are transformed after the compiled march, at the cost of a few array operations.
With q = 1 - m/2 and p = q - m eta, the damage from a_s to a is (a**q - a_s**q) / q, under eta
a_s**(m eta) (a**p - a_s**p) / p.  A law whose F is a table over crack length (model.geometry)
has h(a) = (F(a) sqrt(pi a))**m and no closed form: the damage since a_s is integrated on a
grid of GRID_POINTS cracks from a_s to held_m, evenly in ln a, per sample (the same map to
~1e-6 of the damage; `_map_tabled`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
import torch
from torch import Tensor

from model.cells import DamageKernel
from model.geometry import GeometryTable
from model.geometry_trend import equal_life_slope, measured_trend
from model.integrate import LoadHistory, Observations
from model.physics import ParisLaw, stress_intensity_range

# sd of the slope of ln F in ln a beyond the measured cracks (Extrapolation.slope_sd), chosen on
# fleets whose geometry factor accelerates, stays flat and falls off there
# (benchmarks/extrapolation.py, benchmarks/RESULTS.md): a secant finite-width factor rises by
# 0.15-0.3 per unit ln a between a_crit / 2.5 and a_crit
DEFAULT_SLOPE_SD = 0.1
# The trend's prior mean where nothing fitted reads one and the law's geometry factor is a
# constant (untold_trend): a constant F is an infinite plate's, and a part's factor rises towards
# its edges, as a finite width's does, ln F ~ UNTOLD_RISE (a / a_crit)**2 (a fall, a stiffener
# ahead, is the exception).  Held at 0 (the physics' own claim) the physics chosen on fleets
# inspected once at year 2 flagged 5-11 of 13-20 inspected tails that reach a_crit (the oracle
# 12-20), and Hudak's specimens' lives ran 5-15 % long.  Chosen on fleets inspected early, once
# and sparsely whose factor accelerates, is flat and falls off, and on Hudak's data
# (benchmarks/RESULTS.md): a slope of 0.1 per unit ln a at every distance false-alarmed where F
# is flat and the data end far below a_crit.  A table of F over crack length declares the
# part's rise: the prior mean is 0 beyond it.
UNTOLD_RISE = 0.07
# The trend taken beyond the data lies in [0, MAX_TREND_SLOPE]: a falling geometry factor gets no
# credit where no crack was measured (a noisy fit's curvature, carried from cracks near a_crit,
# read -2.4 on a fleet inspected once with 8 % sizing error), and a rise past F doubling per
# e-fold of crack is no geometry factor of a part in service.
MAX_TREND_SLOPE = 1.0
# |p| below this is taken as this (the damage integral's log limit)
_MIN_POWER = 1e-6
# cracks from a_s to held_m on which a geometry table's damage integral is tabulated: the
# trapezoid rule's error in ln a is ~(m/2 - 1)**2 h**2 / 12 of the damage, h = ln(held/a_s) /
# (GRID_POINTS - 1): ~2e-6 for a_s = a_crit / 10
GRID_POINTS = 1025


@dataclass(frozen=True)
class Extrapolation:
    """Beyond seen_crack_m (a_s, m) the geometry factor is scaled by level (a / a_s)**eta, eta
    ~ N(slope, slope_sd**2) per sample (module docstring); m: the growth law's exponent; held_m:
    the crack at which marches hold (model.physics.ParisLaw.held_crack_m); geometry: the law's
    table of F over crack length, None for a constant F (the closed form)."""

    seen_crack_m: float
    slope: float
    slope_sd: float
    m: float
    held_m: float
    geometry: GeometryTable | None = None
    level: float = 1.0

    def __post_init__(self) -> None:
        if not self.seen_crack_m > 0:
            raise ValueError(f"seen_crack_m must be > 0, got {self.seen_crack_m}")
        if not self.slope_sd >= 0:
            raise ValueError(f"slope_sd must be >= 0, got {self.slope_sd}")
        if not self.m > 2:
            raise ValueError(f"m must be > 2 (a crack that accelerates), got {self.m}")
        if not self.level >= 1:
            raise ValueError(f"level must be >= 1, got {self.level}")

    def slopes(self, samples: int, seed: int) -> Tensor:
        """eta of each sample (samples,): stratified normal quantiles shuffled by seed, so that a
        few hundred samples give stable quantiles."""
        generator = torch.Generator().manual_seed(seed + 7919)
        strata = (torch.arange(samples, dtype=torch.float64) + 0.5) / samples
        normal = math.sqrt(2.0) * torch.erfinv(2 * strata - 1)
        order = torch.randperm(samples, generator=generator)
        return self.slope + self.slope_sd * normal[order]

    def beyond(self, cracks: Tensor, eta: Tensor) -> Tensor:
        """cracks (samples, ...) marched with the correction held past a_s, as under sample k's
        eta[k] (samples,): unchanged up to a_s, past it the crack reached with the same damage
        since a_s; past held_m (a crack that ran away) held there."""
        return self._map(cracks, eta, inverse=False)

    def within(self, cracks: Tensor, eta: Tensor) -> Tensor:
        """The inverse of `beyond`: the crack with the held correction that has accumulated the
        same damage since a_s as `cracks` under eta (a march's start, mapped back)."""
        return self._map(cracks, eta, inverse=True)

    def _map(self, cracks: Tensor, eta: Tensor, *, inverse: bool) -> Tensor:
        values = cracks.detach().to(torch.float64).contiguous().numpy()
        slopes = eta.detach().to(torch.float64).contiguous().numpy()
        if values.size and values.size % max(len(slopes), 1):
            raise ValueError("eta must give one slope per sample (cracks' first dimension)")
        out = np.empty_like(values)
        per_sample = values.size // max(len(slopes), 1)
        common = (
            values.reshape(-1),
            slopes,
            per_sample,
            self.seen_crack_m,
            self.m,
            self.held_m,
            inverse,
            self.level**self.m,
        )
        if self.geometry is None:
            _map_each(*common, out.reshape(-1))
        else:
            table = self.geometry
            knots = np.asarray(table.crack_length_m, dtype=np.float64)
            _map_tabled(*common, knots, table.slopes(), table.factor[0], out.reshape(-1))
        return torch.from_numpy(out).to(cracks.dtype)

    def to_dict(self) -> dict[str, float]:
        """What a model file stores (m, held_m and the geometry come from its law)."""
        return {
            "seen_crack_m": self.seen_crack_m,
            "slope": self.slope,
            "slope_sd": self.slope_sd,
            "level": self.level,
        }

    @classmethod
    def under(
        cls, law: ParisLaw, seen_crack_m: float, slope: float, slope_sd: float, level: float = 1.0
    ) -> Extrapolation:
        """The extrapolation beyond seen_crack_m under `law`: its exponent, held crack and table
        of F (a map that took a constant F under a table law would not be the march's)."""
        return cls(
            seen_crack_m, slope, slope_sd, law.m, law.held_crack_m, law.geometry_table, level
        )

    @classmethod
    def from_dict(cls, data: dict[str, float], law: ParisLaw) -> Extrapolation:
        """Inverse of to_dict under `law`; raises ValueError for anything else."""
        try:
            return cls.under(
                law,
                float(data["seen_crack_m"]),
                float(data["slope"]),
                float(data["slope_sd"]),
                float(data.get("level", 1.0)),  # files before the level held none
            )
        except (KeyError, TypeError) as exc:
            raise ValueError(f"not an extrapolation: {exc!r}") from exc


@numba.njit(cache=True, nogil=True)
def _map_each(
    cracks: np.ndarray,
    slopes: np.ndarray,
    per_sample: int,
    seen: float,
    m: float,
    held: float,
    inverse: bool,
    gain: float,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Extrapolation._map, one element at a time: a scalar loop (math.pow has no vector form
    here), so each crack maps alike whatever else is in the batch (a vectorised pow rounds its
    last lanes differently, and a tail's forecast must not depend on the tails beside it)."""
    q = 1.0 - m / 2.0
    for i in range(cracks.size):
        a = cracks[i]
        if not (a > seen and a < held):
            out[i] = a
            continue
        eta = slopes[i // per_sample]
        p = q - m * eta
        if abs(p) < _MIN_POWER:
            p = -_MIN_POWER
        scale = seen ** (m * eta)
        if inverse:
            base = seen**q + q * scale * (a**p - seen**p) / p / gain
            mapped = base ** (1.0 / q) if base > 0 else math.inf
        else:
            base = seen**p + p * gain * ((a**q - seen**q) / q) / scale
            mapped = base ** (1.0 / p) if base > 0 else math.inf
        out[i] = min(mapped, held)


@numba.njit(cache=True, nogil=True)
def _map_tabled(
    cracks: np.ndarray,
    slopes: np.ndarray,
    per_sample: int,
    seen: float,
    m: float,
    held: float,
    inverse: bool,
    gain: float,
    knots: np.ndarray,
    factor_slopes: np.ndarray,
    first_factor: float,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Extrapolation._map under a geometry table: with u = ln(a / a_s) on a grid of GRID_POINTS
    from 0 to ln(held / a_s), the damage since a_s, D(a) = int (F(a) sqrt(a))**-m da (pi**(m/2)
    cancels), by the trapezoid rule in u, and D_eta with the integrand times exp(-m eta u);
    a crack maps through D and D_eta^-1 (`beyond`) or the reverse (`within`), each read
    linearly between grid points.  Every sample's grid depends on its eta alone (batch
    invariance, as _map_each)."""
    width = math.log(held / seen) / (GRID_POINTS - 1)
    weight = np.empty(GRID_POINTS)  # integrand in u at each grid crack, eta = 0
    for j in range(GRID_POINTS):
        a = seen * math.exp(j * width)
        f = first_factor
        for k in range(factor_slopes.shape[0]):
            f += factor_slopes[k] * (min(max(a, knots[k]), knots[k + 1]) - knots[k])
        weight[j] = a * (f * math.sqrt(a)) ** (-m)
    plain = _cumulative(weight, width)
    shaped = np.empty(GRID_POINTS)
    scaled = np.empty(GRID_POINTS)
    current = -1
    for i in range(cracks.size):
        a = cracks[i]
        if not (a > seen and a < held):
            out[i] = a
            continue
        sample = i // per_sample
        if sample != current:
            eta = slopes[sample]
            for j in range(GRID_POINTS):
                scaled[j] = weight[j] * math.exp(-m * eta * j * width)
            shaped[:] = _cumulative(scaled, width)
            current = sample
        source, target = (shaped, plain) if inverse else (plain, shaped)
        u = math.log(a / seen) / width
        j = min(int(u), GRID_POINTS - 2)
        damage = source[j] + (source[j + 1] - source[j]) * (u - j)
        damage = damage / gain if inverse else damage * gain
        if damage >= target[GRID_POINTS - 1]:
            out[i] = held
            continue
        k = np.searchsorted(target, damage, side="right") - 1
        step = (damage - target[k]) / (target[k + 1] - target[k])
        out[i] = min(seen * math.exp((k + step) * width), held)


@numba.njit(cache=True, nogil=True)
def _cumulative(values: np.ndarray, width: float) -> np.ndarray:  # pragma: no cover - compiled
    """The trapezoid rule's running integral of values (evenly spaced by width), from 0."""
    out = np.empty(values.shape[0])
    out[0] = 0.0
    for j in range(1, values.shape[0]):
        out[j] = out[j - 1] + 0.5 * width * (values[j - 1] + values[j])
    return out


def untold_trend(law: ParisLaw, seen_m: float) -> float:
    """The trend's prior mean beyond seen_m (a_s) where no fitted correction reads one: the
    slope in ln a of UNTOLD_RISE (a / a_crit)**2 between a_s and a_crit (0.10 at a_s = 0.7
    a_crit, 0.06 at 0.2 a_crit); 0 where the law's table of F already rises with the crack."""
    ratio = seen_m / law.critical_crack_m
    if law.geometry_table is not None or not 0 < ratio < 1:
        return 0.0
    return UNTOLD_RISE * (1 - ratio**2) / math.log(1 / ratio)


def fitted_extrapolation(
    kernel: DamageKernel,
    law: ParisLaw,
    observations: Observations,
    loads: LoadHistory,
    slope_sd: float,
    row_tail: Tensor | None = None,
) -> Extrapolation:
    """The extrapolation of a fitted model: a_s the longest crack measured below a_crit (the
    law's a0 where none was; a tail measured past a_crit says nothing of the correction between
    the other tails' cracks and a_crit, and taking a_s = a_crit there skipped the trend: a
    scattered secant fleet, benchmarks/extrapolation.py secant-mild-scatter seed 3, its
    inspected p95 error 23.9 % against 15.3 %), the trend within [0, MAX_TREND_SLOPE] and the
    prior spread slope_sd.  The trend: the kernel's correction carried to a_crit (_trend;
    untold_trend's prior mean for the physics alone), moved towards the measured cracks' own
    (model.geometry_trend) by their precisions, the kernel's taken as known to slope_sd: where
    exact inspections tell the curvature (a finite width's, standard error ~0.03) theirs stands,
    where scatter and sizing error hide it (0.6 and more) the kernel's.  loads: the histories the
    observations index (rows), with their damage-equivalent ranges; row_tail: each row's tail
    (None: each row its own)."""
    seen = observations.crack_length_m[observations.measured].double()
    seen = seen[(seen > law.initial_crack_m) & (seen < law.critical_crack_m)]
    top = float(seen.max()) if len(seen) else law.initial_crack_m
    slope, level = untold_trend(law, top), 1.0
    low = max(float(seen.min()), law.initial_crack_m) if len(seen) else top
    if kernel.learned and top > low:  # a trend needs two crack lengths, all below a_crit
        slope, level = _trend(kernel, law, loads.stress_range_mpa, low, top)
    tails = torch.arange(len(loads.lengths)) if row_tail is None else row_tail
    measured = measured_trend(law, loads, observations, tails, top)
    if measured is not None and math.isfinite(measured.slope_se):
        weight = slope_sd**2 / (slope_sd**2 + measured.slope_se**2) if slope_sd > 0 else 0.0
        slope += weight * (measured.slope - slope)
    slope = min(max(slope, 0.0), MAX_TREND_SLOPE)
    return Extrapolation.under(law, top, slope, slope_sd, level)


# crack lengths the correction's trend is read at, over the measured range
_TREND_POINTS = 16


def _trend(
    kernel: DamageKernel, law: ParisLaw, stress_range_mpa: Tensor, low_m: float, top_m: float
) -> tuple[float, float]:
    """The correction's trend carried to a_crit: ln(dK / physics dK) over [low_m, top_m], averaged
    over the flown stress ranges weighted by their damage (dS**m), fitted by a quadratic in a
    and continued to a_crit as the power of a with the same life from a_s to a_crit
    (geometry_trend.equal_life_slope, as the measured cracks' own trend is carried).  A
    quadratic, since geometry factors of cracks that grow towards an edge rise as a**2 at first
    (sec: 1 + (pi a / 2W)**2 / 4), and one that is levelling off (a stiffener ahead) shows it as
    a negative curvature.  The power reaching the quadratic's value at a_crit (before session
    12) rose faster between a_s and a_crit than the truth of a straight rise in a: the calibration
    fleet (benchmarks/calibration.py, its critical tails never inspected) got 3 and 7 false
    alarms and p50 errors of 23-39 % there, against 0 and 2, 4-15 % with the equal life.
    Also the level (Extrapolation.level): the correction's highest over the range against its
    value at top_m."""
    flown = stress_range_mpa[stress_range_mpa > 0].double()
    levels = torch.quantile(flown, torch.linspace(0.05, 0.95, 19, dtype=torch.float64))
    weight = levels**law.m / (levels**law.m).sum()
    lengths = torch.linspace(low_m, top_m, _TREND_POINTS, dtype=torch.float64)
    a = lengths[:, None].expand(-1, len(levels))
    s = levels[None, :].expand(len(lengths), -1)
    with torch.no_grad():
        ratio = kernel(s, a) / stress_intensity_range(s, a, law.geometry)
    log_ratio = (torch.log(ratio.clamp_min(1e-9)) * weight[None, :]).sum(dim=1).numpy()
    x = (lengths.numpy() - top_m) / (top_m - low_m)
    curvature, slope, _ = np.polyfit(x, log_ratio, 2)
    carried = equal_life_slope(law, top_m, top_m - low_m, float(slope), float(curvature))
    level = math.exp(float(log_ratio.max() - log_ratio[-1]))
    return (carried if math.isfinite(carried) else math.copysign(MAX_TREND_SLOPE, slope)), level
