"""One or two quarter-elliptical corner cracks (depth a along the bore, length c on the
surface) at an open hole of radius r in a plate of thickness t and width W under remote
tension, the shape a/c held as given.

Source: Newman and Raju, NASA TM 83200 (1981) and ASTM STP 791 (1983), the corner crack at a
hole: for two symmetric cracks
    K = S sqrt(pi a / Q) [M1 + M2 (a/t)**2 + M3 (a/t)**4] g1 g2 g3 f_phi f_w,
    g2 = (1 + 0.358 l + 1.425 l**2 - 1.578 l**3 + 2.156 l**4) / (1 + 0.13 l**2),
         l = 1 / (1 + (c/r) cos(0.85 phi)),
    g3 = (1 + 0.04 a/c) (1 + 0.1 (1 - cos phi)**2) (0.85 + 0.15 (a/t)**(1/4))   (a/c <= 1;
         (1.13 - 0.09 c/a) in place of (1 + 0.04 a/c) beyond),
    f_w = sqrt(sec(pi r / 2b) sec(pi (2r + n c) / (4(b - c) + 2 n c) sqrt(a/t))), b = W/2,
and for one crack K times sqrt((4/pi + a c / (2 t r)) / (4/pi + a c / (t r))).  Within about
5 % of their finite-element results for 0.2 <= a/c <= 2, a/t < 1, 0.5 <= r/t <= 2,
(r + c)/b < 0.5.  At a = t the crack has broken through the bore: it is then a through crack
at a hole (the 'through_crack_at_hole' case), which this case does not continue into.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from model.crack_cases.base import CrackCase, ValidityLimit
from model.crack_cases.newman_raju import angle_factor, depth_terms, shape_factor, surface_term

POINTS = {"bore": 0.5 * np.pi, "surface": 0.0}
_ASPECT = (0.2, 2.0)
_RADIUS_ON_THICKNESS = (0.5, 2.0)
_WIDTH_LIMIT = 0.5


@dataclass(frozen=True)
class CornerCrackAtHole(CrackCase):
    """hole_diameter_m: 2r; thickness_m: t; width_m: W (hole on the centre line);
    aspect_ratio: a/c, held; cracks: 1 or 2; point: 'bore' (the crack's depth a along the
    bore, phi = pi/2) or 'surface' (its tip on the plate's face, phi = 0)."""

    hole_diameter_m: float
    thickness_m: float
    width_m: float
    aspect_ratio: float
    cracks: int = 1
    point: Literal["bore", "surface"] = "bore"

    type_name = "corner_crack_at_hole"

    def _check(self) -> None:
        if not _ASPECT[0] <= self.aspect_ratio <= _ASPECT[1]:
            raise ValueError(
                f"aspect_ratio (a/c) must lie in [{_ASPECT[0]}, {_ASPECT[1]}], "
                f"got {self.aspect_ratio!r}"
            )
        ratio = 0.5 * self.hole_diameter_m / self.thickness_m
        if not _RADIUS_ON_THICKNESS[0] <= ratio <= _RADIUS_ON_THICKNESS[1]:
            raise ValueError(
                f"hole_diameter_m: the hole's radius over thickness_m must lie in "
                f"[{_RADIUS_ON_THICKNESS[0]}, {_RADIUS_ON_THICKNESS[1]}], got {ratio:.3g}"
            )
        if self.cracks not in (1, 2):
            raise ValueError(f"cracks must be 1 or 2, got {self.cracks!r}")
        if self.point not in POINTS:
            raise ValueError(f"point must be one of {', '.join(POINTS)}, got {self.point!r}")
        if self.hole_diameter_m / self.width_m >= _WIDTH_LIMIT:
            raise ValueError(
                f"width_m must exceed {1 / _WIDTH_LIMIT:g} hole diameters, got {self.width_m:g} m"
            )

    def beta(self, crack_length_m: np.ndarray) -> np.ndarray:
        a = np.asarray(crack_length_m, dtype=np.float64)
        k, phi, n = self.aspect_ratio, POINTS[self.point], self.cracks
        t, r, b = self.thickness_m, 0.5 * self.hole_diameter_m, 0.5 * self.width_m
        c = a / k
        depth = a / t
        m1, m2, m3 = depth_terms(k)
        g1 = surface_term(k, depth, phi)
        lam = 1.0 / (1.0 + (c / r) * np.cos(0.85 * phi))
        g2 = (1.0 + 0.358 * lam + 1.425 * lam**2 - 1.578 * lam**3 + 2.156 * lam**4) / (
            1.0 + 0.13 * lam**2
        )
        lead = (1.0 + 0.04 * k) if k <= 1.0 else (1.13 - 0.09 / k)
        g3 = lead * (1.0 + 0.1 * (1.0 - np.cos(phi)) ** 2) * (0.85 + 0.15 * depth**0.25)
        f_w = np.sqrt(
            1.0
            / np.cos(np.pi * r / (2.0 * b))
            / np.cos(np.pi * (2.0 * r + n * c) / (4.0 * (b - c) + 2.0 * n * c) * np.sqrt(depth))
        )
        f = (m1 + m2 * depth**2 + m3 * depth**4) * g1 * g2 * g3 * angle_factor(k, phi) * f_w
        if n == 1:
            f = f * np.sqrt((4.0 / np.pi + a * c / (2.0 * t * r)) / (4.0 / np.pi + a * c / (t * r)))
        return f / np.sqrt(shape_factor(k))

    def validity(self) -> ValidityLimit:
        through = ValidityLimit(
            self.thickness_m,
            "a/t = 1: the corner crack breaks through the bore and becomes a through crack at "
            "the hole (case through_crack_at_hole)",
        )
        r, b = 0.5 * self.hole_diameter_m, 0.5 * self.width_m
        by_width = (_WIDTH_LIMIT * b - r) * self.aspect_ratio
        if by_width < through.crack_length_m:
            return ValidityLimit(by_width, f"(r + c)/b = {_WIDTH_LIMIT} (Newman-Raju)")
        return through

    def extent_m(self) -> float:
        r, b = 0.5 * self.hole_diameter_m, 0.5 * self.width_m
        return min(self.thickness_m, (b - r) * self.aspect_ratio)

    def extent_reason(self) -> str:
        r, b = 0.5 * self.hole_diameter_m, 0.5 * self.width_m
        if self.thickness_m <= (b - r) * self.aspect_ratio:
            return (
                "a = t: the crack breaks through the bore and becomes a through crack at the hole"
            )
        return "r + c = W/2: the crack's surface length reaches the plate's edge"

    def net_section_factor(self, crack_length_m: np.ndarray) -> np.ndarray:
        a = np.asarray(crack_length_m, dtype=np.float64)
        gross = self.width_m * self.thickness_m
        cracked = self.cracks * 0.25 * np.pi * a * a / self.aspect_ratio
        return gross / (gross - self.hole_diameter_m * self.thickness_m - cracked)
