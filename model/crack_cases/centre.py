"""A centre (middle) crack of length 2a in a plate of width W under remote tension.

Sources: H. Tada, P. C. Paris, G. R. Irwin, The Stress Analysis of Cracks Handbook (1973,
3rd ed. 2000), case 2.1: beta = (1 - 0.025 l**2 + 0.06 l**4) sqrt(sec(pi l / 2)), l = 2a/W,
within 0.1 % of Isida's series solution for any l; C. E. Feddersen, ASTM STP 410 (1967):
beta = sqrt(sec(pi a / W)), within 0.3 % for l <= 0.7.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from model.crack_cases.base import CrackCase, ValidityLimit, secant_factor

# Isida's tabulated range, which Tada's fit reproduces; Feddersen's stated range
_LIMIT = {"tada": 0.9, "feddersen": 0.7}


@dataclass(frozen=True)
class CentreCrack(CrackCase):
    """width_m: the panel's full width W; a is the half crack length."""

    width_m: float
    method: Literal["tada", "feddersen"] = "tada"

    type_name = "centre_crack"

    def _check(self) -> None:
        if self.method not in _LIMIT:
            raise ValueError(f"method must be one of {', '.join(_LIMIT)}, got {self.method!r}")

    def beta(self, crack_length_m: np.ndarray) -> np.ndarray:
        ratio = 2.0 * np.asarray(crack_length_m, dtype=np.float64) / self.width_m
        secant = secant_factor(0.5 * np.pi * ratio)
        if self.method == "feddersen":
            return secant
        return (1.0 - 0.025 * ratio**2 + 0.06 * ratio**4) * secant

    def validity(self) -> ValidityLimit:
        limit = _LIMIT[self.method]
        return ValidityLimit(0.5 * limit * self.width_m, f"2a/W = {limit} ({self.method})")

    def extent_m(self) -> float:
        return 0.5 * self.width_m

    def extent_reason(self) -> str:
        return "2a = W: the crack's tips reach both edges of the panel"

    def net_section_factor(self, crack_length_m: np.ndarray) -> np.ndarray:
        return self.width_m / (self.width_m - 2.0 * np.asarray(crack_length_m, dtype=np.float64))
