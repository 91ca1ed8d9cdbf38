"""The geometry factor's trend beyond the measured cracks, read from the measured cracks with a
correction of crack length alone.

Why.  The kernel's correction is a function of the stress range and the crack length, and over
the measured cracks a network can trade one for the other: on a fleet whose true factor rises as
a**2 towards a panel's edge (a finite width) it learned a nearly straight rise, the trend carried
to a_crit read 0.14 in ln F per ln a where the truth averages 0.47, and a third of the tails that
reached a_crit were not flagged (benchmarks/RESULTS.md).  A geometry factor depends on the crack
alone, and under Paris-type growth each measured crack fixes one point of the damage integral
H(a) = int (F(x) sqrt(x))**-m dx against the damage its flights did (sum dS**m): fifteen exactly
measured tails identify the correction's curvature over the measured cracks, which the network's
fit leaves free.

Model.  A crack a_k measured in history row r after n flights: H(a_k) - H(a_r0) = exp(k + f_t)
D_r(n), D_r(n) = sum of the row's first n damage-equivalent ranges**m, a_r0 the row's initial
crack, k the fleet's constant (C, pi**(m/2), F's level: a constant correction is the fleet's
rate), f_t the tail's own factor where it has two measured cracks or more (its scatter, which
one measurement cannot tell from the curve), 0 otherwise.  F = the law's F times exp(Q(a)),
Q(a) = b1 u + b2 u**2, u = (a - a_s) / (a_s - a_low) over the measured cracks [a_low, a_s].
Fitted by least squares in ln a.  Beyond a_s the quadratic is carried as the power of a with
the same life from a_s to a_crit (the power law of model.extrapolation that reaches a_crit in as
many flights: a power with Q's value at a_crit rises faster in between and false-alarmed 5-8
tails of 25 on the finite-width fleet), with its standard error from the fit's covariance.
Where tails scatter and are measured with error the curvature is not told (standard errors of
0.6 to 47 on the scattered fleets); model.extrapolation weighs the two trends by it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from torch import Tensor

from model.integrate import LoadHistory, Observations
from model.physics import ParisLaw

# scipy's optimizers are imported where a retrain fits the trend: at import they took ~1.3 s of
# every service, worker and command start, most of which never fit one.

# points of the crack grids the damage integrals are tabulated on, evenly in ln a
_GRID = 512
# the least residual sd (in ln a) the standard errors assume: exact inspections fit to ~1e-4,
# which would make the quadratic's own form the only uncertainty left
RESIDUAL_FLOOR = 1e-3
# fewest measured cracks, and the least span top / low, the curvature is read from
MIN_CRACKS = 6
MIN_SPAN = 1.2
# a trend steeper than this either way (ln F per ln a) is no geometry factor's: a fit that
# reads one has read the scatter (linear-sparse: -2.9 +- 7)
SLOPE_BOUND = 5.0


@dataclass(frozen=True)
class MeasuredTrend:
    """The measured cracks' trend beyond a_s: slope, the equal-life power of a (module
    docstring), and its standard error slope_se; curvature: b2."""

    slope: float
    slope_se: float
    curvature: float


# a trial curvature far off overflows the damage integral: that trial's misfit is large, which
# is all the fit needs of it
@np.errstate(over="ignore", invalid="ignore", divide="ignore")
def measured_trend(
    law: ParisLaw,
    loads: LoadHistory,
    observations: Observations,
    row_tail: Tensor,
    seen_m: float,
) -> MeasuredTrend | None:
    """The trend of ln F beyond seen_m (a_s: the extrapolation's, the longest crack measured
    below a_crit; module docstring); None where fewer than MIN_CRACKS cracks were measured
    after a flight between a0 and a_crit, they span less than MIN_SPAN, or the fit reads no
    geometry factor's trend."""
    rows = observations.aircraft.numpy()
    flights = observations.flights.numpy()
    cracks = observations.crack_length_m.double().numpy()
    keep = observations.measured.numpy() & (flights > 0)
    keep &= (cracks > law.initial_crack_m) & (cracks < law.critical_crack_m)
    rows, flights, cracks = rows[keep], flights[keep], cracks[keep]
    if len(cracks) < MIN_CRACKS or not cracks.max() >= MIN_SPAN * cracks.min():
        return None
    low, top = float(cracks.min()), float(cracks.max())
    stress = loads.stress_range_mpa.double().numpy()
    damage = np.cumsum(stress**law.m, axis=1)[rows, flights - 1]
    starts = (
        np.full(len(stress), law.initial_crack_m)
        if loads.initial_crack_m is None
        else loads.initial_crack_m.double().numpy()
    )[rows]
    _, per_crack, counts = np.unique(
        row_tail.numpy()[rows], return_inverse=True, return_counts=True
    )
    free = counts >= 2  # tails whose own factor the data can tell from the curve
    index = np.full(len(counts), -1)  # -1: the 0 appended to the parameters
    index[free] = 3 + np.arange(int(free.sum()))
    own = index[per_crack]

    span = top - low
    below = _Integral(law, min(float(starts.min()), low), law.critical_crack_m, top, span)
    start_at = np.log(starts)

    def misfit(theta: np.ndarray) -> np.ndarray:
        cumulative = below.cumulative(below.shape(theta[1], theta[2]))
        factor = np.append(theta, 0.0)[own]
        target = np.interp(start_at, below.ln_a, cumulative) + np.exp(theta[0] + factor) * damage
        reached = np.interp(target, cumulative, below.ln_a)
        return np.log(cracks) - reached

    start = np.zeros(3 + int(free.sum()))
    physics = below.cumulative(0.0)
    needed = np.interp(np.log(cracks), below.ln_a, physics) - np.interp(
        start_at, below.ln_a, physics
    )
    start[0] = float(np.median(np.log(np.maximum(needed, 1e-300) / np.maximum(damage, 1e-300))))
    from scipy.optimize import least_squares
    from scipy.sparse import lil_matrix

    from model.sparse_difference import SparseDifference

    # each crack depends on the fleet's three parameters and its own tail's factor alone
    sparsity = lil_matrix((len(cracks), len(start)), dtype=np.int8)
    sparsity[:, :3] = 1
    tailed = np.flatnonzero(own >= 0)
    sparsity[tailed, own[tailed]] = 1
    jacobian = SparseDifference(misfit, sparsity)
    fit = least_squares(jacobian.fun, start, method="trf", x_scale="jac", jac=jacobian)
    if not (fit.success and np.isfinite(fit.fun).all()):
        return None
    dof = max(len(cracks) - len(start), 1)
    sigma = max(math.sqrt(2 * fit.cost / dof), RESIDUAL_FLOOR)

    beyond = _Integral(law, seen_m, law.critical_crack_m, top, span)
    curve = fit.x[1:3]
    slope = beyond.equal_life_slope(*curve)
    if not math.isfinite(slope):
        return None
    jac = fit.jac.toarray() if hasattr(fit.jac, "toarray") else fit.jac
    try:
        covariance = sigma**2 * np.linalg.inv(jac.T @ jac)[1:3, 1:3]
    except np.linalg.LinAlgError:
        return MeasuredTrend(slope, math.inf, float(curve[1]))
    step = 1e-4
    gradient = np.array(
        [(beyond.equal_life_slope(*(curve + step * unit)) - slope) / step for unit in np.eye(2)]
    )
    variance = float(gradient @ covariance @ gradient)
    se = math.sqrt(variance) if variance >= 0 else math.inf  # NaN (a bound crossed): inf
    return MeasuredTrend(slope, se, float(curve[1]))


def equal_life_slope(law: ParisLaw, seen_m: float, span_m: float, b1: float, b2: float) -> float:
    """The power of a / a_s whose life from a_s = seen_m to a_crit equals that under the
    correction exp(b1 u + b2 u**2), u = (a - seen_m) / span_m (NaN beyond +-SLOPE_BOUND): how a
    quadratic read over the measured cracks is carried beyond them (module docstring)."""
    return _Integral(law, seen_m, law.critical_crack_m, seen_m, span_m).equal_life_slope(b1, b2)


class _Integral:
    """The damage integral H over a grid of cracks from low_m to high_m, evenly in ln a, under
    the law's F times exp(b1 u + b2 u**2), u = (a - origin_m) / span_m."""

    def __init__(
        self, law: ParisLaw, low_m: float, high_m: float, origin_m: float, span_m: float
    ) -> None:
        self.ln_a = np.linspace(math.log(low_m), math.log(high_m), _GRID)
        cracks = np.exp(self.ln_a)
        table = law.geometry_table
        factor = (
            np.full(_GRID, law.geometry_factor)
            if table is None
            else np.interp(cracks, table.crack_length_m, table.factor)
        )
        # (F sqrt(a))**-m a: the integrand in ln a
        self.weight = (factor * np.sqrt(cracks)) ** (-law.m) * cracks
        self.u = (cracks - origin_m) / span_m
        self.m = law.m

    def shape(self, b1: float, b2: float) -> np.ndarray:
        """ln of the correction on the grid: b1 u + b2 u**2."""
        return b1 * self.u + b2 * self.u**2

    def cumulative(self, log_factor: np.ndarray | float) -> np.ndarray:
        """H from the grid's first crack to each, the correction exp(log_factor) (trapezoid in
        ln a)."""
        values = self.weight * np.exp(-self.m * log_factor)
        steps = 0.5 * (values[1:] + values[:-1]) * np.diff(self.ln_a)
        return np.concatenate([[0.0], np.cumsum(steps)])

    def life(self, log_factor: np.ndarray) -> float:
        """H from the grid's first crack to its last."""
        return float(self.cumulative(log_factor)[-1])

    def equal_life_slope(self, b1: float, b2: float) -> float:
        """The power eta of a / a_s (a_s: the grid's first crack) with the life to the grid's
        last crack that exp(b1 u + b2 u**2) gives; NaN outside [-SLOPE_BOUND, SLOPE_BOUND]."""
        target = math.log(self.life(self.shape(b1, b2)))
        rise = self.ln_a - self.ln_a[0]

        def gap(eta: float) -> float:
            return math.log(self.life(eta * rise)) - target

        from scipy.optimize import brentq

        if not gap(-SLOPE_BOUND) > 0 > gap(SLOPE_BOUND):  # life falls as eta rises
            return math.nan
        return float(brentq(gap, -SLOPE_BOUND, SLOPE_BOUND))
