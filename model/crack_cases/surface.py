"""A semi-elliptical surface crack (depth a, surface length 2c) in a plate of thickness t and
width W under remote tension, its shape a/c held as given.

Source: Newman and Raju, Eng. Fract. Mech. 15 (1981) 185-192 (and NASA TM 83200):
    K = S sqrt(pi a / Q) [M1 + M2 (a/t)**2 + M3 (a/t)**4] g f_phi f_w,
    f_w = sqrt(sec(pi c / W sqrt(a/t))),
within 5 % of their finite-element results for 0 < a/c <= 2, a/t < 0.8 (as published;
they give a/t < 1 with the accuracy unstated past 0.8), c/b < 0.5 (b = W/2) and any phi.
beta is K / (S sqrt(pi a)): the march's crack is the depth.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from model.crack_cases.base import CrackCase, ValidityLimit, secant_factor
from model.crack_cases.newman_raju import angle_factor, depth_terms, shape_factor, surface_term

_DEPTH_LIMIT = 0.8
_HALF_WIDTH_LIMIT = 0.5
POINTS = {"depth": 0.5 * np.pi, "surface": 0.0}


@dataclass(frozen=True)
class SurfaceCrack(CrackCase):
    """thickness_m: t; width_m: W; aspect_ratio: a/c, held as the crack grows; point: where
    on the front K is taken ('depth': the deepest point, 'surface': where it meets the
    surface)."""

    thickness_m: float
    width_m: float
    aspect_ratio: float
    point: Literal["depth", "surface"] = "depth"

    type_name = "surface_crack"

    def _check(self) -> None:
        if not 0.0 < self.aspect_ratio <= 2.0:
            raise ValueError(f"aspect_ratio (a/c) must lie in (0, 2], got {self.aspect_ratio!r}")
        if self.point not in POINTS:
            raise ValueError(f"point must be one of {', '.join(POINTS)}, got {self.point!r}")

    def beta(self, crack_length_m: np.ndarray) -> np.ndarray:
        a = np.asarray(crack_length_m, dtype=np.float64)
        k, phi = self.aspect_ratio, POINTS[self.point]
        depth = a / self.thickness_m
        m1, m2, m3 = depth_terms(k)
        half_length = a / k
        f_w = secant_factor(np.pi * half_length / self.width_m * np.sqrt(depth))
        f = (m1 + m2 * depth**2 + m3 * depth**4) * surface_term(k, depth, phi)
        return f * angle_factor(k, phi) * f_w / np.sqrt(shape_factor(k))

    def validity(self) -> ValidityLimit:
        by_depth = _DEPTH_LIMIT * self.thickness_m
        by_width = _HALF_WIDTH_LIMIT * 0.5 * self.width_m * self.aspect_ratio
        if by_width < by_depth:
            return ValidityLimit(by_width, f"c/b = {_HALF_WIDTH_LIMIT} (Newman-Raju)")
        return ValidityLimit(by_depth, f"a/t = {_DEPTH_LIMIT} (Newman-Raju)")

    def extent_m(self) -> float:
        return min(self.thickness_m, 0.5 * self.width_m * self.aspect_ratio)

    def net_section_factor(self, crack_length_m: np.ndarray) -> np.ndarray:
        a = np.asarray(crack_length_m, dtype=np.float64)
        gross = self.width_m * self.thickness_m
        return gross / (gross - 0.5 * np.pi * a * a / self.aspect_ratio)
