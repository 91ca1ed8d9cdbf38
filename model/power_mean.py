"""(low**p + frac (high**p - low**p))**(1/p), compiled: the factor grid's interpolation of a
crack between two marched growth factors (model.fleet_sampling), in a module of its own so that
model.compile_ahead can compile it without importing the forecast's modules."""

from __future__ import annotations

import numba
import numpy as np


def warm_up() -> None:
    """Compile (or load) power_mean (compile_ahead)."""
    ones = np.ones((1, 1))
    power_mean(ones, ones, ones, -0.9, np.empty((1, 1)))


@numba.njit(cache=True, nogil=True)
def power_mean(
    low: np.ndarray, high: np.ndarray, frac: np.ndarray, power: float, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """One element at a time: a vectorised pow rounds some lanes differently, which made a
    tail's samples depend, in the last bit, on how many tails were sampled with it (a forecast
    must equal its tail's part of the ranking)."""
    flat_low, flat_high, flat_frac, flat_out = (
        low.reshape(-1),
        high.reshape(-1),
        frac.reshape(-1),
        out.reshape(-1),
    )
    for i in range(flat_low.size):
        a, b = flat_low[i] ** power, flat_high[i] ** power
        flat_out[i] = (a + flat_frac[i] * (b - a)) ** (1.0 / power)
