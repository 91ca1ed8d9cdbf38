"""A semi-elliptical surface crack (depth a, surface length 2c) in a plate of thickness t and
width W under remote tension, its shape a/c held as given or evolving as the crack grows.

Source: Newman and Raju, Eng. Fract. Mech. 15 (1981) 185-192 (and NASA TM 83200):
    K = S sqrt(pi a / Q) [M1 + M2 (a/t)**2 + M3 (a/t)**4] g f_phi f_w,
    f_w = sqrt(sec(pi c / W sqrt(a/t))),
within 5 % of their finite-element results for 0 < a/c <= 2, a/t < 0.8 (as published;
they give a/t < 1 with the accuracy unstated past 0.8), c/b < 0.5 (b = W/2) and any phi.
beta is K / (S sqrt(pi a)): the march's crack is the depth.

An evolving shape follows the two-point growth both tips obey under a Paris-type law of
exponent m, dc/da = (K_c / K_a)**m (the method of the Newman-Raju paper's own life
predictions, and of NASGRO's and AFGROW's surface cracks), integrated by RK4 in ln a from the
shape given at `shape_at_depth_m`; K_c/K_a is the ratio of F at phi = 0 and phi = pi/2.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import numpy as np

from model.crack_cases.base import CrackCase, ValidityLimit, secant_factor
from model.crack_cases.newman_raju import angle_factor, depth_terms, shape_factor, surface_term

_DEPTH_LIMIT = 0.8
_HALF_WIDTH_LIMIT = 0.5
_ASPECT_LIMIT = 2.0
POINTS = {"depth": 0.5 * np.pi, "surface": 0.0}
# RK4 steps in ln a per factor 1e4 of depth: the path is smooth in ln a (halving the step
# changes a/c by < 1e-5)
_PATH_STEPS = 1000


@dataclass(frozen=True)
class SurfaceCrack(CrackCase):
    """thickness_m: t; width_m: W; aspect_ratio: a/c (held, or at shape_at_depth_m where it
    evolves, and held below that depth); point: where on the front K is taken ('depth': the deepest point, 'surface':
    where it meets the surface); growth_exponent: the law's m, with which the shape evolves
    (null: held), and then shape_at_depth_m, the depth at which aspect_ratio is the shape."""

    thickness_m: float
    width_m: float
    aspect_ratio: float
    point: Literal["depth", "surface"] = "depth"
    growth_exponent: float | None = None
    shape_at_depth_m: float | None = None

    type_name = "surface_crack"

    def _check(self) -> None:
        if not 0.0 < self.aspect_ratio <= _ASPECT_LIMIT:
            raise ValueError(f"aspect_ratio (a/c) must lie in (0, 2], got {self.aspect_ratio!r}")
        if self.point not in POINTS:
            raise ValueError(f"point must be one of {', '.join(POINTS)}, got {self.point!r}")
        if self.growth_exponent is not None:
            if not 1.0 <= self.growth_exponent <= 10.0:
                raise ValueError(
                    f"growth_exponent must lie in [1, 10], got {self.growth_exponent!r}"
                )
            if self.shape_at_depth_m is None or self.shape_at_depth_m >= self.thickness_m:
                raise ValueError(
                    "shape_at_depth_m: an evolving shape needs the depth (m, below thickness_m) "
                    f"at which aspect_ratio holds, got {self.shape_at_depth_m!r}"
                )

    def aspect_at(self, crack_length_m: np.ndarray) -> np.ndarray:
        """a/c at each depth (m): the given shape, or its evolved path."""
        a = np.asarray(crack_length_m, dtype=np.float64)
        if self.growth_exponent is None:
            return np.full_like(a, self.aspect_ratio)
        log_a, aspect = _shape_path(self)
        return np.interp(np.log(np.maximum(a, 1e-300)), log_a, aspect)

    def beta(self, crack_length_m: np.ndarray) -> np.ndarray:
        a = np.asarray(crack_length_m, dtype=np.float64)
        return _front_factor(self, a, self.aspect_at(a), POINTS[self.point])

    def validity(self) -> ValidityLimit:
        by_depth = ValidityLimit(
            _DEPTH_LIMIT * self.thickness_m, f"a/t = {_DEPTH_LIMIT} (Newman-Raju)"
        )
        crack = np.geomspace(1e-4 * self.thickness_m, by_depth.crack_length_m, 4096)
        aspect = self.aspect_at(crack)
        past_width = crack / aspect > _HALF_WIDTH_LIMIT * 0.5 * self.width_m
        past_shape = aspect > _ASPECT_LIMIT
        limits = [by_depth]
        if past_width.any():
            first = crack[int(np.argmax(past_width))]
            limits.append(ValidityLimit(float(first), f"c/b = {_HALF_WIDTH_LIMIT} (Newman-Raju)"))
        if past_shape.any():
            first = crack[int(np.argmax(past_shape))]
            limits.append(ValidityLimit(float(first), f"a/c = {_ASPECT_LIMIT} (Newman-Raju)"))
        return min(limits, key=lambda limit: limit.crack_length_m)

    def extent_m(self) -> float:
        if self.growth_exponent is None:
            return min(self.thickness_m, 0.5 * self.width_m * self.aspect_ratio)
        crack = np.geomspace(1e-4 * self.thickness_m, self.thickness_m, 4096)
        severed = crack / self.aspect_at(crack) >= 0.5 * self.width_m
        return float(crack[int(np.argmax(severed))]) if severed.any() else self.thickness_m

    def extent_reason(self) -> str:
        if self.extent_m() < self.thickness_m:
            return "c = W/2: the crack's surface length reaches both edges of the plate"
        return "a = t: the crack reaches the back face"

    def net_section_factor(self, crack_length_m: np.ndarray) -> np.ndarray:
        a = np.asarray(crack_length_m, dtype=np.float64)
        gross = self.width_m * self.thickness_m
        return gross / (gross - 0.5 * np.pi * a * a / self.aspect_at(a))


def _front_factor(case: SurfaceCrack, a: np.ndarray, aspect: np.ndarray, phi: float) -> np.ndarray:
    """K / (S sqrt(pi a)) at angle phi of fronts of depth a and shape a/c (arrays alike)."""
    depth = a / case.thickness_m
    m1, m2, m3 = depth_terms(aspect)
    f_w = secant_factor(np.pi * (a / aspect) / case.width_m * np.sqrt(depth))
    f = (m1 + m2 * depth**2 + m3 * depth**4) * surface_term(aspect, depth, phi)
    return f * angle_factor(aspect, phi) * f_w / np.sqrt(shape_factor(aspect))


@lru_cache(maxsize=64)
def _shape_path(case: SurfaceCrack) -> tuple[np.ndarray, np.ndarray]:
    """(ln a, a/c) along the evolving shape from shape_at_depth_m to t: dc/du = a (F_c /
    F_a)**m in u = ln a by RK4, forward only (backward the shape runs away from the path every
    front converges to, a/c ~ 0.8 in tension); the half length is capped where the front
    would leave the plate's width.  Below shape_at_depth_m the shape is the given one
    (np.interp holds the first value)."""
    assert case.growth_exponent is not None and case.shape_at_depth_m is not None
    m, t = case.growth_exponent, case.thickness_m

    def slope(u: float, c: float) -> float:
        a = np.array([np.exp(u)])
        aspect = a / min(c, 0.5 * case.width_m)
        ratio = _front_factor(case, a, aspect, 0.0) / _front_factor(case, a, aspect, 0.5 * np.pi)
        return float(a[0] * ratio[0] ** m)

    start, end = np.log(case.shape_at_depth_m), np.log(t)
    steps = max(2, int(_PATH_STEPS * (end - start) / np.log(1e4)))
    u = np.linspace(start, end, steps + 1)
    c = np.empty_like(u)
    c[0] = case.shape_at_depth_m / case.aspect_ratio
    for k in range(steps):
        h = u[k + 1] - u[k]
        k1 = slope(u[k], c[k])
        k2 = slope(u[k] + h / 2, c[k] + h * k1 / 2)
        k3 = slope(u[k] + h / 2, c[k] + h * k2 / 2)
        k4 = slope(u[k + 1], c[k] + h * k3)
        c[k + 1] = c[k] + h * (k1 + 2 * k2 + 2 * k3 + k4) / 6
    return u, np.exp(u) / c
