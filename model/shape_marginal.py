"""The measured cracks' likelihood of the geometry factor's shape with every tail's own growth
factor integrated out (model.geometry_posterior's fit).

Why integrated, not fitted beside the shape: with one or two cracks a tail, a tail's factor and
the shape are confounded, and the joint mode of both (each factor's prior a penalty) shrinks
the factors towards the fleet's centre and lets a rising shape explain the cracks' spread in
their place, a rise the truth need not have (one round at year 1 read ln F rising 0.18 by
a_crit where the truth was flat).  The marginal has no such pull.

How: a tail's factor f ~ N(0, tau**2) enters its cracks only through exp(c + f), so its
integral is one-dimensional: adaptive Gauss-Hermite quadrature about the tail's own mode
(found by Gauss-Newton, all tails at once), exact for a normal integrand and close for a
tail's near-normal one, as mixed models integrate their random effects.
"""

from __future__ import annotations

import numpy as np

# quadrature nodes per tail about its mode: the integrand is near normal in ln F
NODES = 7
# Gauss-Newton steps to each tail's mode from the fleet's centre: the same at every call, so
# that the marginal is a function of its parameters alone (its differences, the fit's gradient)
_STEPS = 30
_CONVERGED = 1e-10
_HALVINGS = 30


class TailMarginal:
    """-log p(cracks | c, shape) with the tails' factors integrated out, as a function of theta
    = (c, the shape's whitened slopes) whose shape's damage integral `cumulative` and
    integrand `integrand` (on the grid ln_a) the caller gives."""

    def __init__(
        self,
        ln_a: np.ndarray,
        start_ln_a: np.ndarray,
        measured_ln_a: np.ndarray,
        crack_sd: np.ndarray,
        damage: np.ndarray,
        tail: np.ndarray,
    ) -> None:
        self.ln_a, self.start_ln_a, self.measured = ln_a, start_ln_a, measured_ln_a
        self.crack_sd, self.damage, self.tail = crack_sd, damage, tail
        self.tau = 1.0
        self.tails = int(tail.max()) + 1
        nodes, weights = np.polynomial.hermite.hermgauss(NODES)
        self.nodes, self.log_weights = nodes, np.log(weights) + nodes**2

    def __call__(
        self, c: float, tau: float, cumulative: np.ndarray, integrand: np.ndarray
    ) -> float:
        self.tau = tau
        origin = hermite(self.ln_a, cumulative, integrand, self.start_ln_a)
        modes, curvature = self._modes(c, origin, cumulative, integrand)
        sd = curvature**-0.5
        logs = np.stack(
            [
                self._log_joint(c, modes + np.sqrt(2.0) * sd * z, origin, cumulative, integrand)
                for z in self.nodes
            ]
        ) + self.log_weights[:, None]
        top = logs.max(axis=0)
        per_tail = top + np.log(np.exp(logs - top).sum(axis=0)) + np.log(np.sqrt(2.0) * sd)
        # each tail's factor's normal density's own constant, -ln tau: tau is a parameter
        return -float(per_tail.sum()) + self.tails * np.log(tau)

    def _reached(
        self,
        c: float,
        factors: np.ndarray,
        origin: np.ndarray,
        cumulative: np.ndarray,
        integrand: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Each crack's ln a reached by its damage under the tails' factors, and the damage
        term exp(c + f) D (for the derivative)."""
        grown = np.exp(c + factors[self.tail]) * self.damage
        return hermite(cumulative, self.ln_a, 1.0 / integrand, origin + grown), grown

    def _log_joint(
        self,
        c: float,
        factors: np.ndarray,
        origin: np.ndarray,
        cumulative: np.ndarray,
        integrand: np.ndarray,
    ) -> np.ndarray:
        """log p(tail's cracks, f) per tail up to constants."""
        reached, _ = self._reached(c, factors, origin, cumulative, integrand)
        misfit = np.bincount(
            self.tail, ((self.measured - reached) / self.crack_sd) ** 2, self.tails
        )
        return -0.5 * (misfit + (factors / self.tau) ** 2)

    def _modes(
        self, c: float, origin: np.ndarray, cumulative: np.ndarray, integrand: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Each tail's mode of f and the Gauss-Newton curvature there."""
        modes = np.zeros(self.tails)
        value = self._log_joint(c, modes, origin, cumulative, integrand)
        weight = 1.0 / self.crack_sd**2
        for _ in range(_STEPS):
            reached, grown = self._reached(c, modes, origin, cumulative, integrand)
            # d ln a / d f: the damage term over the integrand of H in ln a where it reached
            # (past the grid's end, its last)
            slope = grown / np.interp(reached, self.ln_a, integrand)
            gradient = np.bincount(
                self.tail, slope * (self.measured - reached) * weight, self.tails
            )
            gradient -= modes / self.tau**2
            curvature = np.bincount(self.tail, slope**2 * weight, self.tails) + self.tau**-2
            step = gradient / curvature
            if np.abs(step).max() < _CONVERGED:
                break
            # halve a tail's step until its log joint does not fall (a safeguarded ascent: the
            # mode, and so the marginal, move continuously with the parameters)
            for _ in range(_HALVINGS):
                trial = self._log_joint(c, modes + step, origin, cumulative, integrand)
                worse = trial < value - _CONVERGED * (1.0 + np.abs(value))
                if not worse.any():
                    break
                step = np.where(worse, 0.5 * step, step)
            better = ~worse
            modes = np.where(better, modes + step, modes)
            value = np.where(better, trial, value)
        reached, grown = self._reached(c, modes, origin, cumulative, integrand)
        slope = grown / np.interp(reached, self.ln_a, integrand)
        curvature = np.bincount(self.tail, slope**2 * weight, self.tails) + self.tau**-2
        return modes, curvature


def hermite(x: np.ndarray, y: np.ndarray, slope: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The cubic Hermite interpolant through (x, y) with derivatives `slope` (x increasing) at
    `at`, linear outside with the ends' slopes: continuous in its derivative where linear
    interpolation is not, so that the marginal is smooth for the fit's differences."""
    k = np.clip(np.searchsorted(x, at) - 1, 0, len(x) - 2)
    h = x[k + 1] - x[k]
    t = np.clip((at - x[k]) / h, 0.0, 1.0)
    t2, t3 = t * t, t * t * t
    inside = (
        (2 * t3 - 3 * t2 + 1) * y[k]
        + (t3 - 2 * t2 + t) * h * slope[k]
        + (-2 * t3 + 3 * t2) * y[k + 1]
        + (t3 - t2) * h * slope[k + 1]
    )
    below = y[0] + slope[0] * np.minimum(at - x[0], 0.0)
    above = y[-1] + slope[-1] * np.maximum(at - x[-1], 0.0)
    return np.where(at < x[0], below, np.where(at > x[-1], above, inside))
