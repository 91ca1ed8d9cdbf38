"""A single edge crack of depth a in a plate of width W under remote tension (ends free to
rotate).

Sources: Tada, Paris and Irwin, The Stress Analysis of Cracks Handbook (1973), case 2.10:
beta = sqrt(tan(x) / x) (0.752 + 2.02 l + 0.37 (1 - sin x)**3) / cos x, x = pi l / 2, l = a/W,
within 0.5 % for any l; W. F. Brown and J. E. Srawley, ASTM STP 410 (1966):
beta = 1.12 - 0.231 l + 10.55 l**2 - 21.72 l**3 + 30.39 l**4, within 0.5 % for l <= 0.6.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from model.crack_cases.base import CrackCase, ValidityLimit

_LIMIT = {"tada": 0.8, "brown_srawley": 0.6}


@dataclass(frozen=True)
class SingleEdgeCrack(CrackCase):
    """width_m: the plate's width W, from the cracked edge to the free one."""

    width_m: float
    method: Literal["tada", "brown_srawley"] = "tada"

    type_name = "edge_crack"

    def _check(self) -> None:
        if self.method not in _LIMIT:
            raise ValueError(f"method must be one of {', '.join(_LIMIT)}, got {self.method!r}")

    def beta(self, crack_length_m: np.ndarray) -> np.ndarray:
        ratio = np.asarray(crack_length_m, dtype=np.float64) / self.width_m
        if self.method == "brown_srawley":
            return 1.12 - 0.231 * ratio + 10.55 * ratio**2 - 21.72 * ratio**3 + 30.39 * ratio**4
        x = 0.5 * np.pi * ratio
        safe = np.where(x > 1e-8, x, 1.0)
        tan_over_x = np.where(x > 1e-8, np.tan(safe) / safe, 1.0)
        polynomial = 0.752 + 2.02 * ratio + 0.37 * (1.0 - np.sin(x)) ** 3
        return np.sqrt(tan_over_x) * polynomial / np.cos(x)

    def validity(self) -> ValidityLimit:
        limit = _LIMIT[self.method]
        return ValidityLimit(limit * self.width_m, f"a/W = {limit} ({self.method})")

    def extent_m(self) -> float:
        return self.width_m

    def extent_reason(self) -> str:
        return "a = W: the crack reaches the far edge of the strip"

    def net_section_factor(self, crack_length_m: np.ndarray) -> np.ndarray:
        return self.width_m / (self.width_m - np.asarray(crack_length_m, dtype=np.float64))
