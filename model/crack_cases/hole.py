"""One or two through cracks of length a from the edge of an open hole of radius r, under
remote tension normal to the cracks.

Source: O. L. Bowie, J. Math. Phys. 35 (1956) 60-71, tabulated in Tada, Paris and Irwin,
The Stress Analysis of Cracks Handbook (1973); the polynomial fits in l = 1 / (1 + a/r),
    one crack:  beta = 0.707 - 0.18 l + 6.55 l**2 - 10.54 l**3 + 6.85 l**4
    two cracks: beta = 1 - 0.15 l + 3.46 l**2 - 4.47 l**3 + 3.52 l**4
(the fits the fatigue textbooks quote, e.g. J. Schijve, Fatigue of Structures and Materials,
2009; checked here against Bowie's tabulated values, tests/model/crack_cases/test_hole.py), which
tend to 3.36 (1.12 Kt) at a -> 0 and to the crack of length a + 2r (one) or 2(a + r) (two)
far from the hole.  A finite width W is compounded with Feddersen's secant on that equivalent
crack, sqrt(sec(pi (n a / 2 + r) / W)), the compounding the USAF Damage Tolerant Design
Handbook uses (an approximation: within a few % for (2r + n a)/W <= 0.5).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from model.crack_cases.base import UNBOUNDED_M, CrackCase, ValidityLimit, secant_factor

# where the compounded width correction stays within its few per cent
_WIDTH_LIMIT = 0.5
_COEFFICIENTS = {
    1: (0.707, -0.18, 6.55, -10.54, 6.85),
    2: (1.0, -0.15, 3.46, -4.47, 3.52),
}


@dataclass(frozen=True)
class CrackAtHole(CrackCase):
    """hole_diameter_m: the hole's diameter 2r; cracks: 1 or 2 (symmetric, diametrically
    opposite); width_m: the plate's width W with the hole on its centre line (null: an
    infinite plate)."""

    hole_diameter_m: float
    cracks: int = 1
    width_m: float | None = None

    type_name = "through_crack_at_hole"

    def _check(self) -> None:
        if self.cracks not in _COEFFICIENTS:
            raise ValueError(f"cracks must be 1 or 2, got {self.cracks!r}")
        if self.width_m is not None and self.hole_diameter_m / self.width_m >= _WIDTH_LIMIT:
            raise ValueError(
                f"width_m must exceed {1 / _WIDTH_LIMIT:g} hole diameters "
                f"({self.hole_diameter_m / _WIDTH_LIMIT:g} m), got {self.width_m:g} m"
            )

    def beta(self, crack_length_m: np.ndarray) -> np.ndarray:
        a = np.asarray(crack_length_m, dtype=np.float64)
        radius = 0.5 * self.hole_diameter_m
        ratio = 1.0 / (1.0 + a / radius)
        beta = np.zeros_like(ratio)
        for power, coefficient in enumerate(_COEFFICIENTS[self.cracks]):
            beta = beta + coefficient * ratio**power
        if self.width_m is not None:
            beta = beta * secant_factor(np.pi * (0.5 * self.cracks * a + radius) / self.width_m)
        return beta

    def validity(self) -> ValidityLimit:
        if self.width_m is None:
            return ValidityLimit(UNBOUNDED_M, "an infinite plate (Bowie)")
        limit = (_WIDTH_LIMIT * self.width_m - self.hole_diameter_m) / self.cracks
        return ValidityLimit(
            limit, f"(2r + {self.cracks} a)/W = {_WIDTH_LIMIT} (width compounding)"
        )

    def extent_m(self) -> float:
        if self.width_m is None:
            return UNBOUNDED_M
        return 0.5 * (self.width_m - self.hole_diameter_m)

    def extent_reason(self) -> str:
        if self.width_m is None:
            return f"an infinite plate: nothing to sever (a_crit searched to a = {UNBOUNDED_M:g} m)"
        return "a = (W - 2r)/2: the crack reaches the plate's edge"

    def net_section_factor(self, crack_length_m: np.ndarray) -> np.ndarray | None:
        if self.width_m is None:
            return None
        a = np.asarray(crack_length_m, dtype=np.float64)
        return self.width_m / (self.width_m - self.hole_diameter_m - self.cracks * a)
