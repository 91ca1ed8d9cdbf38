"""The tests' hand calculations of a critical crack: the first root of a function of one crack
length, found by a uniform scan and plain bisection (not the code's log-spaced scan and
Brent's method, model.crack_cases.residual_strength), and the strengths they share."""

from __future__ import annotations

import math
from collections.abc import Callable

# a toughness (MPa sqrt(m)) and yield strength (MPa) of the order of a 2024-T3 sheet's
K_C = 100.0
SIGMA_Y = 350.0
# cracks scanned for the first sign change before bisecting (uniform in a)
_SCAN = 20_000


def bisect(function: Callable[[float], float], low: float, high: float) -> float:
    """The root of `function` between low (< 0) and high (> 0): plain bisection to 1e-13 m."""
    assert function(low) < 0 < function(high)
    while high - low > 1e-13:
        middle = 0.5 * (low + high)
        low, high = (middle, high) if function(middle) < 0 else (low, middle)
    return 0.5 * (low + high)


def first_root(function: Callable[[float], float], low: float, high: float) -> float:
    """The smallest a in (low, high) where `function` turns >= 0, math.inf where it never
    does: the first sign change of a uniform scan, bisected."""
    assert function(low) < 0
    step = (high - low) / _SCAN
    previous = low
    for k in range(1, _SCAN + 1):
        a = low + k * step
        if function(a) >= 0:
            return bisect(function, previous, a)
        previous = a
    return math.inf


def by_criterion(fracture: float, net_yield: float, extent: float) -> tuple[float, str]:
    """a_crit and the criterion that governs, from each criterion's own crack (inf: never)."""
    return min((fracture, "fracture"), (net_yield, "net_section_yield"), (extent, "extent"))
