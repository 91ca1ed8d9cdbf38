"""Fast Euler march of the damage cell: a fused numba kernel with an analytic (adjoint) backward.

The recurrence is the one `DamageCell` (Euler step) steps with `model.integrate.march`:

    a_t = a_{t-1} + f * C * max(dK(dS_t, a_{t-1}), 0)**m      (one step per flight; padded steps keep a)

for the three kernels of `model.cells` (physics, MLP, physics * (1 + MLP)), Paris' growth law
(Walker's through its input; the NASGRO equation's threshold and fracture terms multiply it,
model.nasgro, in loops of their own), the Euler step and a per-aircraft growth factor f
(default 1).  The sequential march
pays Python and torch dispatch per step (~150 us), which dominates: with one step per flight and
7,300 flights the work per step is a few hundred flops per aircraft.

Design, chosen by measurement (benchmarks/speed.py; 60 aircraft x 7,300 flights, MLP#1, wall
time, best of 20, on the shared 2-core development machine):

* Forward: one compiled loop, flights outer and aircraft inner, so that every network layer is a
  short contiguous loop over aircraft that LLVM vectorises.  The state of each flight sits in
  (lanes,) buffers, lanes = aircraft rounded up to 32 (no scalar loop remainders); only the
  trajectory is stored, nothing per step for the backward.
* Backward: the adjoint recurrence instead of autograd through 7,300 steps,

      lambda_{t-1} = dL/da_{t-1} + lambda_t * (1 + d(da_t)/d a_{t-1})
      dL/dtheta   += lambda_t * d(da_t)/dtheta

  walking the flights backwards and recomputing each step's hidden activations from the stored
  trajectory, so memory stays O(aircraft * flights) for any network size.
* tanh, expm1 (elu) and pow are inlined, branch-free arithmetic (model/fast_march_math.py), not
  libm calls: libm's are opaque to the vectoriser.  With libm (a first version) a training epoch
  was 28x faster than eager and a forecast 3x; with the inlined versions ~55-60x and ~17-21x
  (forward ~9 ms, backward ~13 ms against ~2 s eager).  They agree with libm to a few ulp.
* Single-threaded: splitting the aircraft over 2 threads (numba prange, one task per chunk of
  aircraft for the whole march) measured 2x slower (18.5 against 8.8 ms for 60 aircraft, 85
  against 42 ms for 300) on the shared machine; see also model/runtime.py.
* The kernels release the GIL (nogil): API threads keep serving while a worker thread trains.
* Arithmetic is float64 inside the kernel whatever the input dtype; float32 inputs get float32
  outputs and gradients (within ~3e-6 of the float32 sequential march over 7,300 flights, which
  carries its own rounding).  One compiled signature per kernel keeps the cached compile short.

Semantics match the torch cells: dK is clamped at 0 before the power (so a negative network
output grows nothing), and the physics dK uses sqrt(pi * max(a, 0)).  A geometry factor given
as a table over crack length (model.geometry) is read at each step's crack by the same formula
as in torch, and its slope enters the adjoint (d dK / d a = dK (1 / 2a + F'(a) / F(a))); a
constant F keeps its own loops, so that path runs as fast and gives the same bits as before
tables (benchmarks/march_speed.py).  Where a = 0 exactly, the
derivative of sqrt(a) is taken as 0 (torch yields nan there).  The gradient flows to the network's
weights and biases, the initial crack and the growth factor; not to the stress ranges (`unsupported_reason` says
so, and the caller falls back to the sequential march).  Gradients are first order only (the
backward is itself not differentiable); higher-order derivatives need the sequential march.

The parts: this module is the torch side (autograd function, argument checks, warm-up);
model/fast_march_packing.py turns a kernel into flat arrays and says which cells the compiled
march supports; model/fast_march_loops.py holds the compiled forward loops (and the forward that
reads a few points without a trajectory, `fast_march_at`, and the pair that reads and
differentiates a few points without handing torch the trajectory, `fast_march_points`),
model/fast_march_adjoint.py the adjoint sweeps, and model/fast_march_math.py the inlined
elementary functions they call.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import torch
from torch import Tensor
from torch.autograd.function import once_differentiable

from model.cells import DamageCell, InputBox, ResidualKernel
from model.fast_march_adjoint import march_backward, march_backward_points
from model.fast_march_loops import (
    march_forward,
    march_read,
    march_record,
    network,
)
from model.fast_march_packing import (
    KIND_PHYSICS,
    KIND_RESIDUAL,
    PackedKernel,
    pack_kernel,
    unsupported_reason,
)
from model.fast_march_stress import READ_AGAIN, float64_array
from model.flat import flatten, unflatten
from model.growth_laws import GROWTH_LAWS, GrowthLaw
from model.physics import ParisLaw

# The compiled loops run over this many lanes: the aircraft rounded up to a multiple of 32, so
# that the SIMD loops (8 doubles per AVX-512 register, unrolled 4x by LLVM) never fall into
# their scalar remainder.  With 60 aircraft that remainder alone took about half the time.
_LANES = 32
# A march that only reads (fast_march_at) rounds up to one AVX-512 register instead: its loops
# are elementwise, so its lanes' values do not depend on how many lanes there are, and a lane
# marched is a lane paid for (300 tails: 304 lanes, 40.9 against 43.3 ms a 7,300-flight
# march at 320).  A march with a gradient keeps _LANES: the adjoint's sums over lanes are
# reassociated (fast_march_adjoint._mlp_backward), so its bits depend on the lane count.
_READ_LANES = 8


def _march_inputs(
    packed: PackedKernel,
    law: ParisLaw,
    growth_law: GrowthLaw,
    stress_range_mpa: Tensor,
    lengths: Tensor,
    growth_factor: Tensor,
    parameters: tuple[Tensor, ...],
) -> tuple[Any, ...]:
    """What the compiled loops march, for a march with a gradient (_LANES a pad): stress
    (aircraft, flights), flights flown, growth factor (lanes,), lanes, the network's tuple and
    the law's c, m, terms and held crack."""
    aircraft = stress_range_mpa.shape[0]
    lanes = -(-aircraft // _LANES) * _LANES
    stress = float64_array(stress_range_mpa)
    flown = lengths.detach().cpu().to(torch.int64).contiguous().numpy()
    factor = np.ones(lanes)
    factor[:aircraft] = float64_array(growth_factor)
    net = network(packed, flatten(parameters).numpy())
    c, m, terms = growth_law.march_constants(law.constants)
    return stress, flown, factor, lanes, net, c, m, terms, float(law.held_crack_m)


def _gradients(
    ctx: Any, grad_initial: np.ndarray, grad_theta: np.ndarray, grad_factor: np.ndarray
) -> tuple[Tensor, Tensor, list[Tensor]]:
    """An adjoint sweep's gradients as torch wants them back: the initial cracks', the growth
    factors' and each weight's, in their inputs' dtypes."""
    initial_dtype, factor_dtype = ctx.dtypes
    grads = unflatten(torch.from_numpy(grad_theta), ctx.parameters)
    weights = [g.to(p.dtype) for g, p in zip(grads, ctx.parameters, strict=True)]
    initial = torch.from_numpy(grad_initial).to(initial_dtype)
    return initial, torch.from_numpy(grad_factor).to(factor_dtype), weights


class _FastEulerMarch(torch.autograd.Function):
    @staticmethod
    def forward(
        ctx: Any,
        packed: PackedKernel,
        law: ParisLaw,
        growth_law: GrowthLaw,
        stress_range_mpa: Tensor,
        lengths: Tensor,
        initial_crack_m: Tensor,
        growth_factor: Tensor,
        *parameters: Tensor,
    ) -> Tensor:
        stress, flown, factor, lanes, net, c, m, terms, held = _march_inputs(
            packed, law, growth_law, stress_range_mpa, lengths, growth_factor, parameters
        )
        traj = march_forward(
            stress, flown, float64_array(initial_crack_m), factor, lanes, net, c, m, terms, held
        )
        ctx.march = (stress, flown, traj, factor, lanes, net, c, m, terms, held)
        ctx.dtypes = (initial_crack_m.dtype, growth_factor.dtype)
        ctx.parameters = [p.detach() for p in parameters]
        out = torch.from_numpy(traj).to(stress_range_mpa.dtype)
        # The numpy arrays above may share memory with these tensors: saving them lets autograd
        # refuse a backward after either was modified in place.
        ctx.save_for_backward(stress_range_mpa, out)
        return out

    @staticmethod
    @once_differentiable
    def backward(ctx: Any, grad_trajectory: Tensor) -> tuple[Tensor | None, ...]:
        ctx.saved_tensors  # noqa: B018 (raises if a saved tensor was modified in place)
        stress, flown, traj, factor, lanes, net, c, m, terms, held = ctx.march
        grad_initial, grad_theta, grad_factor = march_backward(
            stress,
            flown,
            traj,
            float64_array(grad_trajectory),
            factor,
            lanes,
            net,
            c,
            m,
            terms,
            held,
        )
        initial, factor, weights = _gradients(ctx, grad_initial, grad_theta, grad_factor)
        return (None, None, None, None, None, initial, factor, *weights)


def fast_march(
    cell: DamageCell,
    stress_range_mpa: Tensor,
    lengths: Tensor,
    initial_crack_m: Tensor,
    growth_factor: Tensor | None = None,
) -> Tensor:
    """Crack length (aircraft, flights + 1) in m: a_t = a_{t-1} + f C max(dK(dS_t, a_{t-1}), 0)**m.

    stress_range_mpa: (aircraft, flights) MPa, zero-padded; lengths: (aircraft,) real flights of
    each (later steps keep the crack); initial_crack_m: (aircraft,) m; growth_factor:
    (aircraft,) f, default 1.  The cell's network weights are read when called, so
    torch.func.functional_call's substitutes are what is marched.  Differentiable with respect
    to the weights, the initial crack and the growth factor.  Raises ValueError when
    `unsupported_reason` names a reason or a shape is off.
    """
    _check_inputs(cell, stress_range_mpa, lengths, initial_crack_m, growth_factor)
    if growth_factor is None:
        growth_factor = torch.ones_like(initial_crack_m)
    packed, parameters = pack_kernel(cell.kernel)
    out: Tensor = _FastEulerMarch.apply(
        packed,
        cell.law,
        GROWTH_LAWS[cell.growth_law],
        stress_range_mpa,
        lengths,
        initial_crack_m,
        growth_factor,
        *parameters,
    )
    return out


class _FastEulerPoints(torch.autograd.Function):
    """_FastEulerMarch read at a few points: the trajectory stays inside (flights-major,
    march_record) and the backward hears the points' gradients alone (march_backward_points)."""

    @staticmethod
    def forward(
        ctx: Any,
        packed: PackedKernel,
        law: ParisLaw,
        growth_law: GrowthLaw,
        stress_range_mpa: Tensor,
        lengths: Tensor,
        initial_crack_m: Tensor,
        growth_factor: Tensor,
        rows: np.ndarray,
        flights: np.ndarray,
        *parameters: Tensor,
    ) -> Tensor:
        stress, flown, factor, lanes, net, c, m, terms, held = _march_inputs(
            packed, law, growth_law, stress_range_mpa, lengths, growth_factor, parameters
        )
        last = int(flights.max()) if len(flights) else 0
        args = (stress, flown, float64_array(initial_crack_m), factor, lanes, net, c, m, terms)
        traj = march_record(*args, held, last)  # (last + 1, lanes)
        # the points by flight, a point read twice in the order read (march_backward_points)
        order = np.argsort(flights, kind="stable")
        ctx.march = (stress, flown, traj, rows[order], flights[order], order, factor, lanes, net)
        ctx.law = (c, m, terms, held)
        ctx.dtypes = (initial_crack_m.dtype, growth_factor.dtype)
        ctx.parameters = [p.detach() for p in parameters]
        # as _FastEulerMarch: a backward after an in-place change of the stress is refused
        ctx.save_for_backward(stress_range_mpa)
        return torch.from_numpy(traj[flights, rows]).to(stress_range_mpa.dtype)

    @staticmethod
    @once_differentiable
    def backward(ctx: Any, grad_points: Tensor) -> tuple[Tensor | None, ...]:
        ctx.saved_tensors  # noqa: B018 (raises if a saved tensor was modified in place)
        stress, flown, traj, rows, flights, order, factor, lanes, net = ctx.march
        grads = float64_array(grad_points)[order]
        grad_initial, grad_theta, grad_factor = march_backward_points(
            stress, flown, traj, rows, flights, grads, factor, lanes, net, *ctx.law
        )
        initial, factor, weights = _gradients(ctx, grad_initial, grad_theta, grad_factor)
        return (None, None, None, None, None, initial, factor, None, None, *weights)


def fast_march_points(
    cell: DamageCell,
    stress_range_mpa: Tensor,
    lengths: Tensor,
    initial_crack_m: Tensor,
    growth_factor: Tensor | None,
    rows: Tensor,
    flights: Tensor,
) -> Tensor:
    """fast_march(...)[rows, flights] (points,), bit for bit, and its gradient (with respect to
    the weights, the initial crack and the growth factor) bit for bit that of indexing
    fast_march's trajectory, without handing the (aircraft, flights + 1) trajectory and its
    gradient through torch: the march stops at the last flight read.  rows, flights: (points,)
    aircraft and flight index (0 = the initial crack) of each point.  Raises ValueError as
    fast_march does, or for a point outside the trajectory."""
    _check_inputs(cell, stress_range_mpa, lengths, initial_crack_m, growth_factor)
    aircraft, steps = stress_range_mpa.shape
    _check_points(rows, flights, aircraft, steps)
    if growth_factor is None:
        growth_factor = torch.ones_like(initial_crack_m)
    packed, parameters = pack_kernel(cell.kernel)
    out: Tensor = _FastEulerPoints.apply(
        packed,
        cell.law,
        GROWTH_LAWS[cell.growth_law],
        stress_range_mpa,
        lengths,
        initial_crack_m,
        growth_factor,
        rows.to(torch.int64).contiguous().numpy(),
        flights.to(torch.int64).contiguous().numpy(),
        *parameters,
    )
    return out


def _check_inputs(
    cell: DamageCell,
    stress_range_mpa: Tensor,
    lengths: Tensor,
    initial_crack_m: Tensor,
    growth_factor: Tensor | None,
) -> None:
    """fast_march's ValueErrors: a cell it cannot march, or a shape that is off."""
    reason = unsupported_reason(cell, stress_range_mpa)
    if reason is not None:
        raise ValueError(f"fast march unavailable: {reason}")
    if stress_range_mpa.dim() != 2:
        raise ValueError("stress_range_mpa must be (aircraft, flights)")
    for name, values in (
        ("initial_crack_m", initial_crack_m),
        ("lengths", lengths),
        ("growth_factor", growth_factor),
    ):
        if values is not None and values.shape != stress_range_mpa.shape[:1]:
            raise ValueError(f"{name} must have one entry per aircraft")


def _check_points(rows: Tensor, flights: Tensor, aircraft: int, steps: int) -> None:
    """Raises ValueError unless rows, flights are (points,) alike inside the trajectory."""
    if rows.shape != flights.shape or rows.dim() != 1:
        raise ValueError("rows and flights must be (points,) alike")
    if len(rows) and not (
        0 <= int(rows.min()) <= int(rows.max()) < aircraft
        and 0 <= int(flights.min()) <= int(flights.max()) <= steps
    ):
        raise ValueError(f"points must lie in [0, {aircraft}) x [0, {steps}]")


def fast_march_at(
    cell: DamageCell,
    stress_range_mpa: Tensor,
    lengths: Tensor,
    initial_crack_m: Tensor,
    growth_factor: Tensor | None,
    rows: Tensor,
    flights: Tensor,
) -> Tensor:
    """fast_march(...)[rows, flights] (points,), without a gradient: the same steps, bit for
    bit, without building the trajectory, each march ending at the last flight read.  A
    residual kernel whose output layer is all zero (a fit's start) marches the physics
    loops: dK * (1 + 0) is dK, and the physics skips the network (~2.5x faster).  rows,
    flights: (points,) aircraft and flight index (0 = the initial crack) of each point.
    Raises ValueError as fast_march does, or for a point outside the trajectory."""
    reason = unsupported_reason(cell, stress_range_mpa)
    if reason is not None:
        raise ValueError(f"fast march unavailable: {reason}")
    aircraft, steps = stress_range_mpa.shape
    _check_points(rows, flights, aircraft, steps)
    packed, parameters = pack_kernel(cell.kernel)
    if packed.kind == KIND_RESIDUAL and not any(bool(p.any()) for p in parameters[-2:]):
        packed = replace(packed, kind=KIND_PHYSICS)
    lanes = -(-aircraft // _READ_LANES) * _READ_LANES
    factor = np.ones(lanes)
    if growth_factor is not None:
        factor[:aircraft] = float64_array(growth_factor)
    order = torch.argsort(flights, stable=True)
    net = network(packed, flatten([p.detach() for p in parameters]).numpy())
    law = cell.law
    c, m, terms = GROWTH_LAWS[cell.growth_law].march_constants(law.constants)
    values = march_read(
        READ_AGAIN.stress(stress_range_mpa),
        lengths.detach().cpu().to(torch.int64).contiguous().numpy(),
        float64_array(initial_crack_m),
        factor,
        lanes,
        net,
        c,
        m,
        terms,
        float(law.held_crack_m),
        rows[order].to(torch.int64).contiguous().numpy(),
        flights[order].to(torch.int64).contiguous().numpy(),
    )
    out = torch.empty(len(rows), dtype=stress_range_mpa.dtype)
    out[order] = torch.from_numpy(values).to(stress_range_mpa.dtype)
    return out


def warm_up() -> None:
    """Compile the march now (or load it from numba's on-disk cache), not on first use.

    A cold compile takes ~10-20 s, a cache load ~0.5 s.  Call this where a service or worker
    starts, or once while building an image, so the first retrain or forecast does not wait.
    """
    kernel = ResidualKernel(((1, "tanh"),), InputBox((0.0, 1.0), (0.0, 1.0))).double()
    initial = torch.ones(1, dtype=torch.float64, requires_grad=True)
    stress = torch.ones(1, 1, dtype=torch.float64)
    cell = DamageCell(kernel, ParisLaw())
    traj = fast_march(cell, stress, torch.ones(1, dtype=torch.int64), initial)
    traj.sum().backward()
