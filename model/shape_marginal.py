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
"""

from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np
from scipy.special import log_ndtr

# quadrature nodes per tail about its mode: the integrand is near normal in ln F
NODES = 7
# Newton steps to each tail's mode from the fleet's centre: the same start at every call, so
# that the marginal is a function of its parameters alone (its differences, the fit's gradient)
_STEPS = 30
_CONVERGED = 1e-9
# halvings of a step that lowers a tail's log joint
_HALVINGS = 30


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
        self.ln_a, self.start_ln_a, self.damage, self.tail = ln_a, start_ln_a, damage, tail
        self.value, self.sd, self.sign = value, sd, sign
        self.sized = sign == 0
        self.tails = int(tail.max()) + 1
        nodes, weights = np.polynomial.hermite.hermgauss(NODES)
        self.nodes, self.log_weights = nodes, np.log(weights) + nodes**2

    def __call__(
        self, c: float, tau: float, cumulative: np.ndarray, integrand: np.ndarray
    ) -> float:
        origin = hermite(self.ln_a, cumulative, integrand, self.start_ln_a)

        def log_joint(factors: np.ndarray) -> np.ndarray:
            grown = np.exp(c + factors[self.tail]) * self.damage
            reached = hermite(cumulative, self.ln_a, 1.0 / integrand, origin + grown)
            return self._log_joint(factors, reached, tau)

        modes, curvature = _modes(log_joint, self.tails, tau)
        sd = curvature**-0.5
        logs = (
            np.stack([log_joint(modes + np.sqrt(2.0) * sd * z) for z in self.nodes])
            + self.log_weights[:, None]
        )
        top = logs.max(axis=0)
        per_tail = top + np.log(np.exp(logs - top).sum(axis=0)) + np.log(np.sqrt(2.0) * sd)
        # each tail's factor's normal density's own constant, -ln tau: tau is a parameter
        return -float(per_tail.sum()) + self.tails * np.log(tau)

    def _log_joint(self, factors: np.ndarray, reached: np.ndarray, tau: float) -> np.ndarray:
        """log p(a tail's cracks, f) per tail, up to constants of the data."""
        z = (reached - self.value) / self.sd
        terms = np.where(self.sized, -0.5 * z**2, log_ndtr(self.sign * z))
        return np.bincount(self.tail, terms, self.tails) - 0.5 * (factors / tau) ** 2


# the step of the difference quotients in a tail's ln factor
_STEP = 1e-4


def _modes(
    log_joint: Callable[[np.ndarray], np.ndarray], tails: int, tau: float
) -> tuple[np.ndarray, np.ndarray]:
    """Each tail's mode of its log joint in f and its curvature there (at least the prior's
    1 / tau**2): Newton from the fleet's centre, the derivatives by central differences (each
    tail's f moves its own terms alone, so one difference serves every tail), a tail's step
    halved until its log joint does not fall (a safeguarded ascent: the mode, and so the
    marginal, move continuously with the parameters)."""
    modes = np.zeros(tails)
    least = tau**-2

    def derivatives(at: np.ndarray, value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        up, down = log_joint(at + _STEP), log_joint(at - _STEP)
        slope = (up - down) / (2 * _STEP)
        return slope, np.maximum(-(up - 2 * value + down) / _STEP**2, least)

    value = log_joint(modes)
    for _ in range(_STEPS):
        slope, curvature = derivatives(modes, value)
        step = slope / curvature
        if np.abs(step).max() < _CONVERGED:
            break
        for _ in range(_HALVINGS):
            trial = log_joint(modes + step)
            worse = trial < value - _CONVERGED * (1.0 + np.abs(value))
            if not worse.any():
                break
            step = np.where(worse, 0.5 * step, step)
        modes = np.where(worse, modes, modes + step)
        value = np.where(worse, value, trial)
    return modes, derivatives(modes, value)[1]


def hermite(x: np.ndarray, y: np.ndarray, slope: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The cubic Hermite interpolant through (x, y) with derivatives `slope` (x increasing) at
    `at`, linear outside with the ends' slopes: continuous in its derivative where linear
    interpolation is not, so that the marginal is smooth for the fit's differences.  Compiled
    (_hermite): the shape's fit calls it ~150,000 times a retrain on a few hundred points, where
    numpy's dozen small operations a call took 85 % of the fit."""
    as_array = np.ascontiguousarray
    return _hermite(
        as_array(x, np.float64),
        as_array(y, np.float64),
        as_array(slope, np.float64),
        as_array(at, np.float64),
    )


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _hermite(x: np.ndarray, y: np.ndarray, slope: np.ndarray, at: np.ndarray) -> np.ndarray:
    """hermite's loop: the same operations in the same order as the vectorised form it
    replaces, bit for bit."""
    out = np.empty(len(at))
    last = len(x) - 1
    for i in range(len(at)):
        a = at[i]
        if a < x[0]:
            out[i] = y[0] + slope[0] * (a - x[0])
        elif a > x[last]:
            out[i] = y[last] + slope[last] * (a - x[last])
        else:
            k = min(max(np.searchsorted(x, a) - 1, 0), last - 1)
            h = x[k + 1] - x[k]
            t = (a - x[k]) / h  # clipped to [0, 1]; a NaN (a NaN point, a repeated knot) stays one
            if t < 0.0:
                t = 0.0
            elif t > 1.0:
                t = 1.0
            t2 = t * t
            t3 = t * t * t
            out[i] = (
                (2 * t3 - 3 * t2 + 1) * y[k]
                + (t3 - 2 * t2 + t) * h * slope[k]
                + (-2 * t3 + 3 * t2) * y[k + 1]
                + (t3 - t2) * h * slope[k + 1]
            )
    return out
