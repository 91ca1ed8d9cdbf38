"""The measured cracks' likelihood of the geometry factor's shape with every tail's own growth
factor integrated out (model.geometry_posterior's fit).

Why integrated, not fitted beside the shape: with one or two cracks a tail, a tail's factor and
the shape are confounded, and the joint mode of both (each factor's prior a penalty) shrinks
the factors towards the fleet's centre and lets a rising shape explain the cracks' spread in
their place, a rise the truth need not have (one round at year 1 read ln F rising 0.18 by
a_crit where the truth was flat).  The marginal has no such pull.

How: a tail's factor f ~ N(0, tau**2) enters its cracks only through exp(c + f), so its
integral is one-dimensional: adaptive Gauss-Hermite quadrature about the tail's own mode
(found by a safeguarded Newton ascent, all tails at once), exact for a normal integrand and
close for a tail's near-normal one, as mixed models integrate their random effects (lme4's
nAGQ).  Written here rather than with a probabilistic-programming library: the integral is
one-dimensional per tail and vectorised over tails, where a sampler (numpyro's NUTS over every
tail's factor) would cost minutes a location, not seconds.

Compiled (numba): the shape's fit evaluates the marginal a few thousand times, each some forty
evaluations of every tail's log joint on a few rows a tail; as numpy's small operations those
took most of a retrain's fit.  One call is one compiled pass, log Phi (log_ndtr) included.
"""

from __future__ import annotations

import math

import numba
import numpy as np

# quadrature nodes per tail about its mode: the integrand is near normal in ln F
NODES = 7
# Newton steps to each tail's mode from the fleet's centre: the same start at every call, so
# that the marginal is a function of its parameters alone (its differences, the fit's gradient)
_STEPS = 30
_CONVERGED = 1e-9
# halvings of a step that lowers a tail's log joint
_HALVINGS = 30
# the step of the difference quotients in a tail's ln factor
_STEP = 1e-4

# what a tail's log joint reads (_negative_log_marginal): c, tau, the damage integral and the
# grid's ln a, the integrand's inverse, where each tail's rows start (offsets), and the rows'
# origin, damage, value, sd and sign
_Data = tuple[
    float,
    float,
    np.ndarray,
    np.ndarray,
    np.ndarray,
    np.ndarray,
    np.ndarray,
    np.ndarray,
    np.ndarray,
    np.ndarray,
    np.ndarray,
]


class TailMarginal:
    """-log p(cracks | c, tau, shape) with the tails' factors integrated out, as a function of c,
    tau and the shape's damage integral `cumulative` with its integrand `integrand` (dH / d ln a
    on the grid ln_a), which the caller gives.

    Each row is a crack measured after its row's summed damage `damage` from its start ln a:
    a size (sign 0: ln measured = `value`, log-normal with sd `sd`) or censored (a crack measured
    past a_crit says only that it reached a_crit, sign +1, value ln a_crit; a no-find that it was
    probably below the method's threshold, sign -1, value ln a50): log Phi(sign (ln a - value) /
    sd), as model.tracking_grid reads both.  Leaving either out selects: without the runaways
    the fastest tails of a round are missing, and a falling factor is read from the rest."""

    def __init__(
        self,
        ln_a: np.ndarray,
        start_ln_a: np.ndarray,
        damage: np.ndarray,
        tail: np.ndarray,
        value: np.ndarray,
        sd: np.ndarray,
        sign: np.ndarray,
    ) -> None:
        order = np.argsort(tail, kind="stable")  # each tail's rows together, in their order
        self.tails = int(tail.max()) + 1
        self.offsets = np.searchsorted(tail[order], np.arange(self.tails + 1)).astype(np.int64)
        self.rows = np.ascontiguousarray(
            np.stack(
                [
                    np.asarray(column, np.float64)[order]
                    for column in (start_ln_a, damage, value, sd, sign)
                ]
            )
        )
        self.ln_a = np.ascontiguousarray(ln_a, np.float64)
        nodes, weights = np.polynomial.hermite.hermgauss(NODES)
        self.nodes, self.log_weights = nodes, np.log(weights) + nodes**2

    def __call__(
        self, c: float, tau: float, cumulative: np.ndarray, integrand: np.ndarray
    ) -> float:
        return float(
            _negative_log_marginal(
                float(c),
                float(tau),
                self.ln_a,
                np.ascontiguousarray(cumulative, np.float64),
                np.ascontiguousarray(integrand, np.float64),
                self.offsets,
                self.rows,
                self.nodes,
                self.log_weights,
            )
        )


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _negative_log_marginal(
    c: float,
    tau: float,
    ln_a: np.ndarray,
    cumulative: np.ndarray,
    integrand: np.ndarray,
    offsets: np.ndarray,
    rows: np.ndarray,
    nodes: np.ndarray,
    log_weights: np.ndarray,
) -> float:
    """TailMarginal's value (rows: each row's start ln a, damage, value, sd and sign, the rows
    of a tail together from offsets[tail]): each tail's mode and curvature (_modes), its
    quadrature about them, and each tail's normal density's own constant, -ln tau (tau is a
    parameter)."""
    start_ln_a, damage, value, sd, sign = rows[0], rows[1], rows[2], rows[3], rows[4]
    origin = np.empty(len(start_ln_a))
    for row in range(len(start_ln_a)):
        origin[row] = _hermite_at(ln_a, cumulative, integrand, start_ln_a[row])
    inverse = 1.0 / integrand
    data = (c, tau, cumulative, ln_a, inverse, offsets, origin, damage, value, sd, sign)
    tails = len(offsets) - 1
    modes, curvature = _modes(data, tails)
    total = 0.0
    logs = np.empty(len(nodes))
    for tail in range(tails):
        width = math.sqrt(2.0) * curvature[tail] ** -0.5
        for k in range(len(nodes)):
            logs[k] = _log_joint(data, tail, modes[tail] + width * nodes[k]) + log_weights[k]
        top = logs.max()
        total += top + math.log(np.exp(logs - top).sum()) + math.log(width)
    return -total + tails * math.log(tau)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _log_joint(data: _Data, tail: int, factor: float) -> float:
    """log p(a tail's cracks, its factor f), up to constants of the data."""
    c, tau, cumulative, ln_a, inverse, offsets, origin, damage, value, sd, sign = data
    total = 0.0
    growth = math.exp(c + factor)
    for row in range(offsets[tail], offsets[tail + 1]):
        reached = _hermite_at(cumulative, ln_a, inverse, origin[row] + growth * damage[row])
        z = (reached - value[row]) / sd[row]
        total += -0.5 * z * z if sign[row] == 0.0 else _log_ndtr(sign[row] * z)
    return total - 0.5 * (factor / tau) ** 2


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _modes(data: _Data, tails: int) -> tuple[np.ndarray, np.ndarray]:
    """Each tail's mode of its log joint in f and its curvature there (at least the prior's
    1 / tau**2): Newton from the fleet's centre, the derivatives by central differences, a
    tail's step halved until its log joint does not fall (a safeguarded ascent: the mode, and
    so the marginal, move continuously with the parameters).  Every tail steps until the
    largest step has converged, as one vectorised ascent would."""
    least = data[1] ** -2.0
    modes = np.zeros(tails)
    value = np.empty(tails)
    curvature = np.empty(tails)
    step = np.empty(tails)
    for tail in range(tails):
        value[tail] = _log_joint(data, tail, 0.0)
    for _ in range(_STEPS):
        largest = 0.0
        for tail in range(tails):
            slope, curvature[tail] = _derivatives(data, tail, modes[tail], value[tail], least)
            step[tail] = slope / curvature[tail]
            largest = max(largest, abs(step[tail]))
        if largest < _CONVERGED:
            break
        for tail in range(tails):
            for _ in range(_HALVINGS):
                trial = _log_joint(data, tail, modes[tail] + step[tail])
                if not trial < value[tail] - _CONVERGED * (1.0 + abs(value[tail])):
                    modes[tail] += step[tail]
                    value[tail] = trial
                    break
                step[tail] *= 0.5
    for tail in range(tails):
        curvature[tail] = _derivatives(data, tail, modes[tail], value[tail], least)[1]
    return modes, curvature


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _derivatives(
    data: _Data, tail: int, at: float, value: float, least: float
) -> tuple[float, float]:
    """A tail's slope and curvature (at least `least`) of its log joint at f = at."""
    up = _log_joint(data, tail, at + _STEP)
    down = _log_joint(data, tail, at - _STEP)
    return (up - down) / (2 * _STEP), max(-(up - 2 * value + down) / _STEP**2, least)


# below this, log Phi's asymptotic series (erfc underflows near -37.5)
_SERIES_BELOW = -37.0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _log_ndtr(x: float) -> float:
    """log Phi(x), within 5e-14 of scipy.special.log_ndtr (tests): log1p of the upper
    tail above -1, the log of the lower tail's erfc down to -37, and the asymptotic series
    below, where erfc underflows."""
    if x > -1.0:
        return math.log1p(-0.5 * math.erfc(x / math.sqrt(2.0)))
    if x > _SERIES_BELOW:
        return math.log(0.5 * math.erfc(-x / math.sqrt(2.0)))
    inverse_square = 1.0 / (x * x)
    term, series = 1.0, 1.0
    for k in range(1, 8):
        term *= -(2 * k - 1) * inverse_square
        series += term
    return -0.5 * x * x - math.log(-x) - 0.5 * math.log(2.0 * math.pi) + math.log(series)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _hermite_at(x: np.ndarray, y: np.ndarray, slope: np.ndarray, a: float) -> float:
    """The cubic Hermite interpolant through (x, y) with derivatives `slope` (x increasing) at
    a, linear outside with the ends' slopes: continuous in its derivative where linear
    interpolation is not, so that the marginal is smooth for the fit's differences."""
    last = len(x) - 1
    if a < x[0]:
        return y[0] + slope[0] * (a - x[0])
    if a > x[last]:
        return y[last] + slope[last] * (a - x[last])
    k = min(max(int(np.searchsorted(x, a)) - 1, 0), last - 1)
    h = x[k + 1] - x[k]
    t = (a - x[k]) / h  # clipped to [0, 1]; a NaN (a NaN point, a repeated knot) stays one
    if t < 0.0:
        t = 0.0
    elif t > 1.0:
        t = 1.0
    t2 = t * t
    t3 = t * t * t
    return (
        (2 * t3 - 3 * t2 + 1) * y[k]
        + (t3 - 2 * t2 + t) * h * slope[k]
        + (-2 * t3 + 3 * t2) * y[k + 1]
        + (t3 - t2) * h * slope[k + 1]
    )


def warm_up() -> None:
    """Compile (or load from numba's cache) the marginal's loops (model.compile_ahead)."""
    knots = np.array([0.0, 1.0, 2.0])
    marginal = TailMarginal(
        knots,
        np.zeros(2),
        np.ones(2),
        np.array([0, 0]),
        np.array([0.5, 1.0]),
        np.ones(2),
        np.array([0.0, -1.0]),
    )
    marginal(0.0, 0.1, knots, np.ones(3))
