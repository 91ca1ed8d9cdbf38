"""Every compiled loop a retrain and a forecast run, compiled (or loaded from numba's on-disk
cache) before the first job asks for it.

numba compiles a loop for each signature at its first call and keeps it in its cache
(`cache=True`), keyed by the source file's content.  A fresh checkout or image has none: its
first retrain compiled ~10 loops on the way, ~40 CPU s of a small four-location retrain at load
7 (2026-11-27), the same again in each process while none had written the cache.  The march's
own warm-up (model.fast_march.warm_up) covered the trajectory and its adjoint alone; this runs
each public entry point once on a one-aircraft input, so every signature the retrain uses
(tests/app/test_compile_ahead.py) is compiled where a service or worker starts, or where its
image is built, not inside a timed job.
"""

from __future__ import annotations

import numpy as np
import torch

from model.block_bootstrap import BlockPools
from model.cells import DamageCell, InputBox, ResidualKernel
from model.extrapolation import Extrapolation
from model.fast_march import fast_march_at, fast_march_points
from model.fast_march import warm_up as compile_march
from model.geometry import GeometryTable
from model.geometry_posterior import ShapePosterior
from model.path_drift import PathDrift
from model.physics import ParisLaw
from model.power_mean import warm_up as warm_power_mean
from model.shape_marginal import warm_up as warm_shape_marginal


def _reads_and_points() -> None:
    """The reads of a few flights (model.fast_march.fast_march_at; a history read a second
    time is read flights-major, another signature) and the points' march with its adjoint
    (fast_march_points, what the joint fit differentiates)."""
    kernel = ResidualKernel(((1, "tanh"),), InputBox((0.0, 1.0), (0.0, 1.0))).double()
    cell = DamageCell(kernel, ParisLaw())
    # two aircraft: a (1, flights) array is C- and Fortran-ordered at once, typed C alone
    stress = torch.ones(2, 2, dtype=torch.float64)
    lengths = torch.full((2,), 2, dtype=torch.int64)
    initial = torch.full((2,), 1e-3, dtype=torch.float64, requires_grad=True)
    rows, flights = torch.zeros(1, dtype=torch.int64), torch.ones(1, dtype=torch.int64)
    for _ in range(2):  # C-ordered, then flights-major
        fast_march_at(cell, stress, lengths, initial.detach(), None, rows, flights)
    fast_march_points(cell, stress, lengths, initial, None, rows, flights).sum().backward()


def _forecast_maps() -> None:
    """The extrapolation beyond the measured cracks (a constant F and a table), the paths'
    drift and the block bootstrap of future loads."""
    cracks = torch.full((1, 2), 2e-3, dtype=torch.float64)
    table = GeometryTable.of((1e-3, 1e-2), (1.0, 1.2))
    law = ParisLaw(initial_crack_m=1e-3, critical_crack_m=5e-3)
    shape = ShapePosterior.prior(law, 0.1)
    for geometry in (None, table):
        extrapolation = Extrapolation(1e-3, shape, 3.0, 5e-2, 1e-3, 5e-3, geometry)
        extrapolation.beyond(cracks, extrapolation.draws(1, seed=0))
    drift = PathDrift(
        0.1, torch.full((1,), 1e-3, dtype=torch.float64), torch.zeros(1, 1, dtype=torch.float64)
    )
    drift.moved(cracks, [0], 5e-2)
    warm_power_mean()
    BlockPools.of([np.ones(3)], seed=0, block_flights=2, n_flights=2).draw(0, 2)


def compile_ahead() -> None:
    """Compile (or load) every loop a retrain and a forecast run: ~1-2 s from a warm cache."""
    compile_march()
    _reads_and_points()
    warm_shape_marginal()
    _forecast_maps()
