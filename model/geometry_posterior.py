"""The geometry factor's shape as a posterior: a Gaussian-process prior on how the factor the
law misses varies over the crack's life, updated by the measured cracks through their summed
damage.

Why.  Inspections pin the correction to the physics only over the cracks they measured; the
tails that matter (about to reach a_crit) are beyond them.  What a forecast needs there is how
far the factor may move from its value at the longest measured crack, and that is a posterior:
the part of the shape the measured cracks tell, and the prior's part they cannot, which grows
with the distance extrapolated however exact the inspections were.  One prior and one
likelihood, so that no gate (how many cracks, what span), clamp (no credit for a fall) or lift
is needed: with no crack measured the posterior is the prior.

Model.  ln F_true(a) = ln F_law(a) + g(x) + c, x = (a - a0) / (a_crit - a0) over the crack's
length: a part's factor departs from a handbook's idealisation through its own dimensions
(finite width, an edge, a hole, a stiffener), as beta(a / W) is tabulated, so the prior is the
same per unit of crack length, not per unit of ln a (which would crowd the long cracks, where
those departures grow, into the last few percent of the prior's span).  g' (the slope of ln F
in x) is a Gaussian process: N(0, s**2) at a0, then Brownian with the same s over the length
(the integrated Wiener process, whose posterior mean is a cubic spline), s = slope_sd ln(a_crit
/ a0): slope_sd is how steeply, in ln F per ln a over the life, a part's factor may plausibly
depart from the law's (the location's setting).  It is represented by its values at KNOTS + 1
evenly spaced x in [0, 1], linear between them and constant outside, so g is linear in them
(`basis`).  The constant c is the fleet's rate (C's level, flat prior).  Under a separable law
a crack a_k measured in history row r after n flights lies where H(a_k) - H(a_r0) = exp(c +
f_t) D_r(n): H(a) = int (F_law e**g sqrt(a))**-m da, D_r(n) the row's summed damage-equivalent
ranges to the power m, a_r0 its initial crack, f_t ~ N(0, tau**2) the tail's own growth factor,
tau the fleet's spread with its half-normal prior (model.fleet_spread).  ln(measured) = ln a_k
+ e_k, e_k ~ N(0, sizing sd**2).  A likelihood costs the measured cracks and a grid, not the
flights.

Posterior.  Each tail's factor is integrated out (model.shape_marginal: with a crack or two a
tail, its factor and the shape are confounded, and fitting both shrinks the factors and reads
a rise in their place); Laplace at each amplitude of the prior (AMPLITUDE_SD) over c, ln tau
and the whitened slopes: the mode, the inverse of the curvature there (the slopes' block); the
amplitudes' mixture weighted by their prior and their Laplace evidence.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import torch
from torch import Tensor

from model.fleet_spread import SPREAD_PRIOR_SD
from model.geometry import MAX_POINTS, GeometryTable
from model.integrate import LoadHistory, Observations, detection_scale
from model.physics import ParisLaw
from model.shape_marginal import TailMarginal
from model.tracking import MAX_GROWTH_SD, SizingError

# intervals of the slope's knots over the life: the process' resolution (its sd changes by
# 1 / sqrt(KNOTS) of s from one knot to the next)
KNOTS = 8
# The prior's amplitude is itself uncertain (how far a part's factor may depart from the law's
# is not known to a factor of two either way): ln k ~ N(0, AMPLITUDE_SD**2), integrated by
# Gauss-Hermite quadrature, each node's posterior weighted by its evidence (the Laplace
# marginal likelihood), so that the data choose how wrong the physics is, and beyond them the
# mixture keeps the heavier tails of the amplitudes they allow
AMPLITUDE_SD = math.log(2.0)
AMPLITUDE_NODES = 5
# points of the table of the corrected geometry factor from a0 to a_s (corrected_law): g's slope
# is linear between its knots, so ln F is within ~1e-4 of its quadratic pieces there
CORRECTION_POINTS = 33
# points of the crack grid the damage integral is tabulated on, evenly in ln a (trapezoid rule)
_GRID = 1024
# the grid goes on past a_crit by this factor: a trial shape or factor may grow a measured crack
# past a_crit, and the misfit must go on growing there (held at a_crit it would have a kink)
_BEYOND = 4.0
# the least tau and sizing sd the rows divide by: a fleet without spread pins each tail's own
# factor to ~0 and exact data pin their cracks, without a division by zero
_LEAST_SD = 1e-4


@dataclass(frozen=True)
class ShapePosterior:
    """A mixture of normals of g's slopes at the knots, one per amplitude of the prior (module
    docstring): weights (summing to 1), means and covariances."""

    weights: tuple[float, ...]
    means: tuple[tuple[float, ...], ...]
    covariances: tuple[tuple[tuple[float, ...], ...], ...]

    @classmethod
    def prior(cls, law: ParisLaw, slope_sd: float) -> ShapePosterior:
        """The shape's prior under `law` (module docstring)."""
        root = prior_root(law, slope_sd)
        zero = np.zeros(KNOTS + 1)
        return cls.mixture(
            [(float(w), zero, (k * k) * root @ root.T) for k, w in zip(*_amplitudes(), strict=True)]
        )

    @classmethod
    def of(cls, mean: np.ndarray, covariance: np.ndarray) -> ShapePosterior:
        """One normal, from arrays (KNOTS + 1,) and (KNOTS + 1, KNOTS + 1)."""
        return cls.mixture([(1.0, mean, covariance)])

    @classmethod
    def mixture(cls, components: list[tuple[float, np.ndarray, np.ndarray]]) -> ShapePosterior:
        """From (weight, mean, covariance) components; weights are normalised."""
        total = sum(w for w, _, _ in components)
        return cls(
            tuple(float(w / total) for w, _, _ in components),
            tuple(tuple(float(v) for v in m) for _, m, _ in components),
            tuple(tuple(tuple(map(float, r)) for r in 0.5 * (c + c.T)) for _, _, c in components),
        )

    @property
    def mean(self) -> np.ndarray:
        """The mixture's mean (KNOTS + 1,)."""
        return np.asarray(self.weights) @ np.asarray(self.means)

    @property
    def covariance(self) -> np.ndarray:
        """The mixture's covariance (KNOTS + 1, KNOTS + 1)."""
        weights, means = np.asarray(self.weights), np.asarray(self.means)
        spread = np.einsum("k,ki,kj->ij", weights, means, means) - np.outer(self.mean, self.mean)
        return np.einsum("k,kij->ij", weights, np.asarray(self.covariances)) + spread

    def corrected_law(self, law: ParisLaw, seen_m: float) -> ParisLaw:
        """`law` with its geometry factor times exp(g) at the posterior mean, up to seen_m (a_s)
        and held there beyond it (where the forecast's draws take over,
        model.extrapolation): the physics with its learned correction inside, as a table the
        compiled march reads at every step.  A table of F keeps its own points beyond a_s."""
        if not seen_m > law.initial_crack_m:
            return law
        table = law.geometry_table
        beyond = () if table is None else tuple(a for a in table.crack_length_m if a > seen_m)
        own = np.geomspace(
            law.initial_crack_m, seen_m, min(CORRECTION_POINTS, MAX_POINTS - len(beyond))
        )
        cracks = np.concatenate([own, beyond])
        base = (
            np.full(len(cracks), law.geometry_factor)
            if table is None
            else table.at(torch.from_numpy(cracks)).numpy()
        )
        shape = basis(life_position(law, np.minimum(cracks, seen_m))) @ self.mean
        return replace(
            law, geometry_table=GeometryTable.of(cracks.tolist(), (base * np.exp(shape)).tolist())
        )

    def rise_sd(self, basis_rows: np.ndarray) -> np.ndarray:
        """sd of basis_rows @ slopes (rows (n, KNOTS + 1)): of g's change between crack pairs."""
        covariance = self.covariance
        return np.sqrt(np.einsum("ij,jk,ik->i", basis_rows, covariance, basis_rows))


def prior_root(law: ParisLaw, slope_sd: float) -> np.ndarray:
    """A (KNOTS + 1, KNOTS + 1) with slopes = A eps, eps standard normal, under the prior: the
    first slope's sd s, each next one's increment s / sqrt(KNOTS)."""
    scale = slope_sd * math.log(law.critical_crack_m / law.initial_crack_m)
    steps = np.full(KNOTS + 1, scale / math.sqrt(KNOTS))
    steps[0] = scale
    return np.tril(np.ones((KNOTS + 1, KNOTS + 1))) * steps[None, :]


def _amplitudes() -> tuple[np.ndarray, np.ndarray]:
    """The prior's amplitudes k (s times k) and their prior weights: Gauss-Hermite nodes of ln k
    ~ N(0, AMPLITUDE_SD**2)."""
    nodes, weights = np.polynomial.hermite_e.hermegauss(AMPLITUDE_NODES)
    return np.exp(AMPLITUDE_SD * nodes), weights / weights.sum()


def life_position(law: ParisLaw, crack_length_m: np.ndarray | float) -> np.ndarray:
    """x = (a - a0) / (a_crit - a0): where a crack lies in the length the shape is over."""
    return position(law.initial_crack_m, law.critical_crack_m, crack_length_m)


def position(initial_m: float, critical_m: float, crack_length_m: np.ndarray | float) -> np.ndarray:
    """life_position from a0 and a_crit."""
    return (np.asarray(crack_length_m, dtype=np.float64) - initial_m) / (critical_m - initial_m)


def per_log_crack(law: ParisLaw) -> np.ndarray:
    """(KNOTS + 1,) d ln a / dx at the knots: a slope of ln F in ln a as the shape's slopes."""
    cracks = law.initial_crack_m + np.linspace(0.0, 1.0, KNOTS + 1) * (
        law.critical_crack_m - law.initial_crack_m
    )
    return (law.critical_crack_m - law.initial_crack_m) / cracks


def basis(x: np.ndarray) -> np.ndarray:
    """(len(x), KNOTS + 1): g(x) = basis(x) @ slopes, g(0) = 0, the slope linear between knots
    and constant beyond x = 0 and 1."""
    x = np.asarray(x, dtype=np.float64)
    knots = np.linspace(0.0, 1.0, KNOTS + 1)
    width = 1.0 / KNOTS
    inside = np.clip(x, 0.0, 1.0)
    out = np.zeros((len(x), KNOTS + 1))
    for i, knot in enumerate(knots):
        # the integral from 0 of the hat function centred on knot i, up to `inside`
        for lo, hi, rising in ((knot - width, knot, True), (knot, knot + width, False)):
            if lo < 0 or hi > 1:
                continue
            t = np.clip((inside - lo) / width, 0.0, 1.0)
            out[:, i] += width * (t**2 / 2 if rising else t - t**2 / 2)
    out[:, 0] += np.minimum(x, 0.0)  # below a0 the first slope goes on
    out[:, KNOTS] += np.maximum(x - 1.0, 0.0)  # past a_crit the last
    return out


# a trial shape far off overflows the damage integral: its misfit is large, which is all the fit
# needs of it
@np.errstate(over="ignore", invalid="ignore", divide="ignore")
def shape_posterior(
    law: ParisLaw,
    loads: LoadHistory,
    observations: Observations,
    row_tail: Tensor,
    sizing: SizingError,
    growth_sd: float,
    slope_sd: float,
) -> ShapePosterior:
    """The shape's posterior given the inspections after a flight (module docstring): the
    cracks sized, those past a_crit and the no-finds, censored; the prior where no crack was
    sized, or where the fit does not converge.  loads:
    the histories the observations index (rows), with their damage-equivalent ranges; row_tail:
    each row's tail; sizing, growth_sd: the fit's sizing error and fleet spread."""
    prior = ShapePosterior.prior(law, slope_sd)
    root = prior_root(law, slope_sd)
    rows = observations.aircraft.numpy()
    flights = observations.flights.numpy()
    measured = observations.crack_length_m.double()
    cracks = measured.numpy()
    missed = ~observations.measured.numpy()
    runaway = ~missed & (cracks >= law.runaway_crack_m)
    sized = ~missed & ~runaway
    keep = flights > 0
    if not (keep & sized).any() or not slope_sd > 0:
        return prior
    # each row's value, sd and sign (model.shape_marginal): a size, a crack past a_crit, a
    # no-find below the method's PoD curve seen through the sizing error
    value = np.where(sized, np.log(np.where(sized, cracks, 1.0)), math.log(law.critical_crack_m))
    sd = sizing.log_sd(torch.from_numpy(np.where(sized, cracks, law.critical_crack_m))).numpy()
    sign = np.where(sized, 0.0, 1.0)
    if missed.any():
        assert observations.detection_a50_m is not None
        a50 = observations.detection_a50_m.double()
        a90 = observations.detection_a90_m
        scale = detection_scale(a50, None if a90 is None else a90.double(), sizing.log_sd(a50))
        value = np.where(missed, np.log(a50.numpy()), value)
        sd = np.where(missed, scale.numpy(), sd)
        sign = np.where(missed, -1.0, sign)
    sd = np.maximum(sd, _LEAST_SD)
    rows, flights, value, sd, sign = rows[keep], flights[keep], value[keep], sd[keep], sign[keep]
    stress = loads.stress_range_mpa.double().numpy()
    damage = np.cumsum(stress**law.m, axis=1)[rows, flights - 1]
    starts = (
        np.full(len(stress), law.initial_crack_m)
        if loads.initial_crack_m is None
        else loads.initial_crack_m.double().numpy()
    )[rows]
    _, own = np.unique(row_tail.numpy()[rows], return_inverse=True)
    tau = max(growth_sd, 0.05)  # where the spread's fit starts
    low = min(float(starts.min()), float(np.exp(value[sign == 0]).min()))
    grid = _Grid(law, low, root)
    start_at = np.log(starts)
    marginal = TailMarginal(grid.ln_a, start_at, damage, own, value, sd, sign)

    def objective(theta: np.ndarray) -> float:
        """-log p(cracks, tau, slopes | c): theta = (c, ln tau, whitened slopes), the tails'
        factors integrated out (model.shape_marginal), tau's half-normal prior (the fleet
        spread's, model.fleet_spread) in ln tau."""
        integrand = grid.integrand(theta[2:])
        tau = math.exp(theta[1])
        spread_prior = 0.5 * (tau / SPREAD_PRIOR_SD) ** 2 - theta[1]
        return (
            marginal(theta[0], tau, grid.integral(integrand), integrand)
            + spread_prior
            + 0.5 * theta[2:] @ theta[2:]
        )

    start = np.zeros(KNOTS + 3)
    start[1] = math.log(tau)
    physics = grid.integral(grid.integrand(np.zeros(KNOTS + 1)))
    on = sign == 0
    needed = np.interp(value[on], grid.ln_a, physics) - np.interp(start_at[on], grid.ln_a, physics)
    start[0] = float(np.median(np.log(np.maximum(needed, 1e-300) / np.maximum(damage[on], 1e-300))))
    components = []
    for amplitude, weight in zip(*_amplitudes(), strict=True):
        grid.scale = amplitude
        fit = _laplace(objective, start)
        if fit is None:
            continue
        mode, covariance, evidence = fit
        scaled, whitened = amplitude * root, covariance[2:, 2:]
        components.append(
            (evidence + math.log(weight), scaled @ mode[2:], scaled @ whitened @ scaled.T)
        )
        start = mode
    if not components:
        return prior
    best = max(log_weight for log_weight, _, _ in components)
    return ShapePosterior.mixture([(math.exp(w - best), m, c) for w, m, c in components])


# the central differences' step of the curvature, in ln C, ln tau and the whitened slopes (each
# of unit scale)
_HESSIAN_STEP = 1e-3


def _laplace(
    objective: Callable[[np.ndarray], float], start: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float] | None:
    """The mode of `objective`, the inverse of its curvature there and the Laplace log evidence
    (up to a constant of the data alone); None where the fit fails."""
    from scipy.optimize import minimize

    # ln tau within spreads from none to any a fleet has (model.fleet_spread's grid): a line
    # search must not step to exp overflow
    bounds = [(None, None), (math.log(_LEAST_SD), math.log(MAX_GROWTH_SD))]
    bounds += [(None, None)] * (len(start) - 2)
    start = start.copy()
    start[1] = min(max(start[1], bounds[1][0]), bounds[1][1])
    fit = minimize(objective, start, method="L-BFGS-B", bounds=bounds)
    if not np.isfinite(fit.fun):
        return None
    mode, size = fit.x, len(fit.x)
    curvature = np.empty((size, size))
    steps = np.eye(size) * _HESSIAN_STEP
    at_mode = objective(mode)
    for i in range(size):
        for j in range(i, size):
            if i == j:
                value = objective(mode + steps[i]) - 2 * at_mode + objective(mode - steps[i])
            else:
                value = (
                    objective(mode + steps[i] + steps[j])
                    - objective(mode + steps[i] - steps[j])
                    - objective(mode - steps[i] + steps[j])
                    + objective(mode - steps[i] - steps[j])
                ) / 4
            curvature[i, j] = curvature[j, i] = value / _HESSIAN_STEP**2
    sign, log_det = np.linalg.slogdet(curvature)
    if not sign > 0:
        return None
    covariance = np.linalg.inv(curvature)
    if not (np.isfinite(covariance).all() and (np.diag(covariance) > 0).all()):
        return None
    # the fleet's constant's flat prior leaves its own curvature in: the same at every amplitude
    return mode, covariance, -float(at_mode) - 0.5 * float(log_det)


class _Grid:
    """The damage integral H over cracks from low_m to _BEYOND a_crit, evenly in ln a, under the
    law's F times exp(g(x)), g's slopes = scale root @ whitened ones (module docstring)."""

    def __init__(self, law: ParisLaw, low_m: float, root: np.ndarray) -> None:
        self.ln_a = np.linspace(math.log(low_m), math.log(_BEYOND * law.critical_crack_m), _GRID)
        cracks = np.exp(self.ln_a)
        table = law.geometry_table
        factor = (
            np.full(_GRID, law.geometry_factor)
            if table is None
            else np.interp(cracks, table.crack_length_m, table.factor)
        )
        self.weight = (factor * np.sqrt(cracks)) ** (-law.m) * cracks  # the integrand in ln a
        self.shape = basis(life_position(law, cracks)) @ root
        self.scale = 1.0  # the prior's amplitude the whitened slopes are under
        self.m = law.m

    def integrand(self, whitened: np.ndarray) -> np.ndarray:
        """dH / d ln a at each crack of the grid."""
        return self.weight * np.exp(-self.m * self.scale * (self.shape @ whitened))

    def integral(self, integrand: np.ndarray) -> np.ndarray:
        """H from the grid's first crack to each (trapezoid in ln a)."""
        steps = 0.5 * (integrand[1:] + integrand[:-1]) * np.diff(self.ln_a)
        return np.concatenate([[0.0], np.cumsum(steps)])
