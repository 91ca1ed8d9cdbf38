"""Maximising a function of one scale parameter (a spread, an sd) over a bounded range."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np


def maximise_scale(f: Callable[[float], float], scan: Sequence[float], steps: int = 40) -> float:
    """argmax of f: the best of the ascending `scan` points, refined by golden-section search
    between its neighbours (f is cheap and unimodal there, not necessarily everywhere); the scan
    point is kept where the refinement does not beat it."""
    values = [f(x) for x in scan]
    best = int(np.argmax(values))
    lo, hi = scan[max(best - 1, 0)], scan[min(best + 1, len(scan) - 1)]
    golden = (math.sqrt(5) - 1) / 2
    for _ in range(steps):
        a, b = hi - golden * (hi - lo), lo + golden * (hi - lo)
        if f(a) >= f(b):
            hi = b
        else:
            lo = a
    x = 0.5 * (lo + hi)
    return x if f(x) >= values[best] else scan[best]
