"""Model-form uncertainty beyond the measured cracks: the geometry factor's shape there, drawn
from its posterior.

Why.  Inspections pin the kernel's correction to the physics only over the crack sizes they
measured; the tails that matter most (about to reach a_crit) are always beyond them.  There the
correction is held at the edge of its input box (model.cells.ResidualKernel), and how wrong
that may be is the geometry factor's posterior (model.geometry_posterior): the shape g(x) of ln
F over the life x, Gaussian in its slopes, what the measured cracks told of it and
the prior's part they could not.

Model.  Beyond a_s, the longest crack measured below a_crit, the geometry factor is the edge's
times exp(g(x) - g(x_s)), g's slopes drawn once per sample from the posterior and shared by every
tail of it (one structure, one unknown shape).  Below a_s nothing changes.

Exact, and outside the march.  Beyond a_s the growth rate separates, da/dN = D_t h(a) with D_t
= f C (dS_t (1 + MLP(dS_t, a_s)))**m of the flight alone and h(a) = (F(a) sqrt(pi a))**m: the
correction is held there, so the crack is a function of the damage accumulated since a_s.  A
trajectory marched with the held correction maps onto the one under the sample's shape crack
by crack (`beyond`), and back (`within`): the damage since a_s, int (F(a) sqrt(a))**-m da with
and without exp(-m (g - g_s)), is integrated on a grid of GRID_POINTS cracks from a_s to held_m,
evenly in ln a, per sample (trapezoid, ~1e-6 of the damage; `_map_shaped`), at the cost of a few
array operations after the compiled march.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np
import torch
from torch import Tensor

from model.geometry import GeometryTable
from model.geometry_posterior import (
    KNOTS,
    ShapePosterior,
    basis,
    per_log_crack,
    position,
    shape_posterior,
)
from model.integrate import LoadHistory, Observations
from model.physics import ParisLaw
from model.tracking import SizingError

# sd of the slope of ln F in ln a that a part's geometry factor may plausibly depart from the
# law's by (model.geometry_posterior's prior): a secant finite-width factor rises by 0.15-0.3
# per unit ln a between a_crit / 2.5 and a_crit, a linear rise of 10 % over the life by 0.04
DEFAULT_SLOPE_SD = 0.1
# cracks from a_s to held_m on which the damage integral is tabulated: the trapezoid rule's
# error in ln a is ~(m/2 - 1)**2 h**2 / 12 of the damage, h = ln(held/a_s) / (GRID_POINTS - 1):
# ~2e-6 for a_s = a_crit / 10
GRID_POINTS = 1025
# |m (g - g_s)| is bounded by this where a drawn shape runs far past held_m (exp's range)
_MAX_EXPONENT = 700.0


@dataclass(frozen=True)
class Extrapolation:
    """Beyond seen_crack_m (a_s, m) the geometry factor is scaled by exp(g(x) - g(x_s)), g's
    slopes ~ shape per sample (module docstring); m: the growth law's exponent; held_m: the crack
    at which marches hold (model.physics.ParisLaw.held_crack_m); initial_m, critical_m: a0 and
    a_crit, the life x is over; geometry: the law's table of F, None for a constant F."""

    seen_crack_m: float
    shape: ShapePosterior
    m: float
    held_m: float
    initial_m: float
    critical_m: float
    geometry: GeometryTable | None = None

    def __post_init__(self) -> None:
        if not self.seen_crack_m > 0:
            raise ValueError(f"seen_crack_m must be > 0, got {self.seen_crack_m}")
        for covariance in np.asarray(self.shape.covariances, dtype=np.float64):
            tolerance = -1e-9 * np.abs(covariance).max()
            if not (
                np.isfinite(covariance).all() and np.linalg.eigvalsh(covariance).min() >= tolerance
            ):
                raise ValueError(
                    f"a shape's covariance must be positive semi-definite, got {covariance}"
                )
        if not self.m > 0:
            raise ValueError(f"m must be > 0, got {self.m}")

    def draws(self, samples: int, seed: int) -> Tensor:
        """The shape's slopes of each sample (samples, KNOTS + 1): scrambled Sobol points, the
        first coordinate choosing the mixture's component by its weight, the others through the
        normal's quantiles, so that a few hundred samples give stable quantiles."""
        size = len(self.shape.means[0])
        engine = torch.quasirandom.SobolEngine(size + 1, scramble=True, seed=seed + 7919)
        uniform = engine.draw(samples, dtype=torch.float64).clamp(1e-9, 1 - 1e-9)
        normal = math.sqrt(2.0) * torch.erfinv(2 * uniform[:, 1:] - 1)
        edges = torch.cumsum(torch.tensor(self.shape.weights, dtype=torch.float64), 0)
        chosen = torch.searchsorted(edges[:-1].contiguous(), uniform[:, 0].contiguous(), right=True)
        out = torch.empty(samples, size, dtype=torch.float64)
        for k, (mean, covariance) in enumerate(
            zip(self.shape.means, self.shape.covariances, strict=True)
        ):
            values, vectors = torch.linalg.eigh(torch.tensor(covariance, dtype=torch.float64))
            root = vectors * values.clamp_min(0).sqrt()
            mine = chosen == k
            out[mine] = torch.tensor(mean, dtype=torch.float64) + normal[mine] @ root.T
        return out

    def beyond(self, cracks: Tensor, shapes: Tensor) -> Tensor:
        """cracks (samples, ...) marched with the correction held past a_s, as under sample k's
        shape shapes[k] (samples, KNOTS + 1): unchanged up to a_s, past it the crack reached with the same
        damage since a_s; past held_m (a crack that ran away) held there."""
        return self._map(cracks, shapes, inverse=False)

    def within(self, cracks: Tensor, shapes: Tensor) -> Tensor:
        """The inverse of `beyond`: the crack with the held correction that has accumulated the
        same damage since a_s as `cracks` under the sample's shape (a march's start, mapped
        back)."""
        return self._map(cracks, shapes, inverse=True)

    def _map(self, cracks: Tensor, shapes: Tensor, *, inverse: bool) -> Tensor:
        values = cracks.detach().to(torch.float64).contiguous().numpy()
        size = len(self.shape.means[0])
        slopes = shapes.detach().to(torch.float64).reshape(-1, size).contiguous().numpy()
        if values.size and values.size % max(len(slopes), 1):
            raise ValueError("shapes must give one shape per sample (cracks' first dimension)")
        out = np.empty_like(values)
        table = self.geometry
        knots = np.asarray(
            (self.initial_m, self.held_m) if table is None else table.crack_length_m,
            dtype=np.float64,
        )
        factor_slopes = np.zeros(1) if table is None else np.asarray(table.slopes())
        first = 1.0 if table is None else float(table.factor[0])
        _map_shaped(
            values.reshape(-1),
            slopes,
            values.size // max(len(slopes), 1),
            self.seen_crack_m,
            self.m,
            self.held_m,
            inverse,
            self._grid_basis(),
            knots,
            factor_slopes.astype(np.float64),
            first,
            out.reshape(-1),
        )
        return torch.from_numpy(out).to(cracks.dtype)

    def _grid_basis(self) -> np.ndarray:
        """(GRID_POINTS, KNOTS + 1): g - g(x_s) on the map's grid from a_s to held_m is this
        times a sample's slopes (model.geometry_posterior.basis)."""
        cracks = np.geomspace(self.seen_crack_m, self.held_m, GRID_POINTS)
        x = position(self.initial_m, self.critical_m, cracks)
        return basis(x) - basis(x[:1])

    def to_dict(self) -> dict[str, Any]:
        """What a model file stores (m, held_m, a0, a_crit and the geometry come from its law)."""
        return {
            "seen_crack_m": self.seen_crack_m,
            "shape_weights": list(self.shape.weights),
            "shape_means": [list(mean) for mean in self.shape.means],
            "shape_covariances": [[list(row) for row in c] for c in self.shape.covariances],
        }

    @classmethod
    def under(cls, law: ParisLaw, seen_crack_m: float, shape: ShapePosterior) -> Extrapolation:
        """The extrapolation beyond seen_crack_m under `law`: its exponent, life, held crack and
        table of F (a map that took a constant F under a table law would not be the march's)."""
        return cls(
            seen_crack_m,
            shape,
            law.m,
            law.held_crack_m,
            law.initial_crack_m,
            law.critical_crack_m,
            law.geometry_table,
        )

    @classmethod
    def from_dict(cls, data: dict[str, Any], law: ParisLaw) -> Extrapolation:
        """Inverse of to_dict under `law`; a file written before the shape's posterior (a slope
        eta ~ N(slope, slope_sd**2) of ln F in ln a beyond a_s) as the shape it was: each knot's
        slope eta d ln a / dx, all one eta.  Raises ValueError for anything else."""
        try:
            seen = float(data["seen_crack_m"])
            if "shape_means" in data:
                weights = np.asarray(data["shape_weights"], dtype=np.float64)
                means = np.asarray(data["shape_means"], dtype=np.float64)
                covariances = np.asarray(data["shape_covariances"], dtype=np.float64)
            else:
                along = per_log_crack(law)[None, :]
                weights = np.ones(1)
                means = float(data["slope"]) * along
                covariances = float(data["slope_sd"]) ** 2 * along[:, :, None] * along[:, None, :]
            size = len(weights)
            if means.shape != (size, KNOTS + 1) or covariances.shape != (
                size,
                KNOTS + 1,
                KNOTS + 1,
            ):
                raise ValueError(f"a shape has {KNOTS + 1} slopes, got {means.shape}")
            components = list(zip(weights, means, covariances, strict=True))
            return cls.under(law, seen, ShapePosterior.mixture(components))
        except (KeyError, TypeError) as exc:
            raise ValueError(f"not an extrapolation: {exc!r}") from exc


@numba.njit(cache=True, nogil=True)
def _map_shaped(
    cracks: np.ndarray,
    shapes: np.ndarray,
    per_sample: int,
    seen: float,
    m: float,
    held: float,
    inverse: bool,
    grid_basis: np.ndarray,
    knots: np.ndarray,
    factor_slopes: np.ndarray,
    first_factor: float,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Extrapolation._map: with u = ln(a / a_s) on a grid of GRID_POINTS from 0 to ln(held /
    a_s), the damage since a_s, D(a) = int (F(a) sqrt(a))**-m da (pi**(m/2) cancels), by the
    trapezoid rule in u, and D_g with the integrand times exp(-m (g - g_s)), g - g_s =
    grid_basis @ the sample's slopes; a crack maps through D and D_g^-1 (`beyond`) or the
    reverse (`within`), each read linearly between grid points.  A scalar loop, and every
    sample's grid depends on its shape alone: a tail's forecast must not depend on the tails
    beside it."""
    width = math.log(held / seen) / (GRID_POINTS - 1)
    weight = np.empty(GRID_POINTS)  # integrand in u at each grid crack, g = g_s
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
            for j in range(GRID_POINTS):
                rise = 0.0
                for k in range(shapes.shape[1]):
                    rise += grid_basis[j, k] * shapes[sample, k]
                exponent = min(max(-m * rise, -_MAX_EXPONENT), _MAX_EXPONENT)
                scaled[j] = weight[j] * math.exp(exponent)
            shaped[:] = _cumulative(scaled, width)
            current = sample
        source, target = (shaped, plain) if inverse else (plain, shaped)
        u = math.log(a / seen) / width
        j = min(int(u), GRID_POINTS - 2)
        damage = source[j] + (source[j + 1] - source[j]) * (u - j)
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


def fitted_extrapolation(
    law: ParisLaw,
    observations: Observations,
    loads: LoadHistory,
    sizing: SizingError,
    growth_sd: float,
    slope_sd: float,
    row_tail: Tensor | None = None,
) -> Extrapolation:
    """The extrapolation of a fitted model: a_s the longest crack measured below a_crit (the
    law's a0 where none was: a crack measured past a_crit says nothing of the shape between the
    other cracks and a_crit), the shape's posterior given the measured cracks
    (model.geometry_posterior) under the fit's sizing error and fleet spread.  loads: the
    histories the observations index (rows), with their damage-equivalent ranges; row_tail:
    each row's tail (None: each row its own)."""
    seen = observations.crack_length_m[observations.measured].double()
    seen = seen[(seen > law.initial_crack_m) & (seen < law.critical_crack_m)]
    top = float(seen.max()) if len(seen) else law.initial_crack_m
    tails = torch.arange(len(loads.lengths)) if row_tail is None else row_tail
    shape = shape_posterior(law, loads, observations, tails, sizing, growth_sd, slope_sd)
    return Extrapolation.under(law, top, shape)
