"""Process-wide CPU thread settings for model work (training, forecasts, benchmarks).

Why one thread by default: the march is sequential in time, so each torch op works on one
flight's (aircraft,) slice, far too small for intra-op parallelism to pay.  Worse, torch's
default pool (one OpenMP thread per core) synchronises at every op; on a shared machine, with
another process holding a core, each barrier waits for a descheduled thread and we measured a
training epoch collapse from ~1.3 s to 25-34 s.  The compiled march (model/fast_march.py) is
single-threaded by design, so numba's pool is left alone (touching it would start its threads).
Scale out with processes (one worker per core), not threads.
"""

from __future__ import annotations

import os

import torch

THREADS_ENV = "FLEETPINN_THREADS"


def configure_threads(n: int | None = None) -> int:
    """Set torch's intra-op thread count and return it.

    n: threads to use; None reads the FLEETPINN_THREADS environment variable, else 1.
    Raises ValueError if the count is not a positive integer.
    """
    if n is None:
        raw = os.environ.get(THREADS_ENV, "1")
        try:
            n = int(raw)
        except ValueError:
            raise ValueError(f"{THREADS_ENV} must be a positive integer, got {raw!r}") from None
    if n < 1:
        raise ValueError(f"thread count must be >= 1, got {n}")
    torch.set_num_threads(n)
    return n


def warm_up() -> None:
    """Compile every loop a retrain and a forecast run now (or load them from numba's cache),
    not in the first job or request (model.compile_ahead)."""
    from model.compile_ahead import compile_ahead  # imports torch's and numba's worlds

    compile_ahead()
