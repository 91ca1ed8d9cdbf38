"""Fast Euler march of the damage cell: a fused numba kernel with an analytic (adjoint) backward.

The recurrence is the one `EulerDamageCell` steps with `model.integrate.march`:

    a_t = a_{t-1} + C * max(dK(dS_t, a_{t-1}), 0)**m      (one step per flight; padded steps keep a)

for the three kernels of `model.cells` (physics, MLP, physics * (1 + MLP)).  The sequential march
pays Python and torch dispatch per step (~150 us), which dominates: with one step per flight and
7,300 flights the work per step is a few hundred flops per aircraft.

Design, chosen by measurement on the 2-core development machine (see benchmarks/speed.py):

* Forward: one numba loop, flights outer and aircraft inner, so each layer of the network is a
  short contiguous loop over aircraft (states are stored (flights, aircraft)).  Only the
  trajectory is kept; nothing per step is stored for the backward.
* Backward: the adjoint recurrence instead of autograd through 7,300 steps,

      lambda_{t-1} = dL/da_{t-1} + lambda_t * (1 + d(da_t)/d a_{t-1})
      dL/dtheta   += lambda_t * d(da_t)/dtheta

  walking the flights backwards and recomputing the network's hidden activations of each step
  from the stored trajectory, so memory stays O(aircraft * flights) for any network size.
* Arithmetic is float64 inside the kernel whatever the input dtype; float32 inputs get float32
  outputs and gradients.  One compiled signature per kernel keeps the first (cached) compile short.
* Single-threaded: the inner loop over 60-300 aircraft is too short to amortise numba's parallel
  dispatch per flight, and the machines this runs on share their cores (see model/runtime.py).

Semantics match the torch cells: dK is clamped at 0 before the power (so a negative network
output grows nothing), and the physics dK uses sqrt(pi * max(a, 0)).  Where a = 0 exactly, the
derivative of sqrt(a) is taken as 0 (torch yields nan there).  The gradient flows to the network's
weights and biases, and to the initial crack; not to the stress ranges (`unsupported_reason` says
so, and the caller falls back to the sequential march).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from numba import njit
from torch import Tensor
from torch.autograd.function import once_differentiable

from model.cells import DamageKernel, MLPKernel, PhysicsKernel, ResidualKernel
from model.nets import MLP
from model.physics import ParisLaw

_KIND_CODES: dict[type[DamageKernel], int] = {PhysicsKernel: 0, MLPKernel: 1, ResidualKernel: 2}
_ACTIVATION_CODES = {"linear": 0, "tanh": 1, "elu": 2}
_PHYSICS, _MLP, _RESIDUAL = 0, 1, 2
_TANH, _ELU = 1, 2


@dataclass(frozen=True)
class PackedKernel:
    """A damage kernel's structure as flat arrays a compiled march can read.

    sizes: (layers + 1,) layer widths, input first; activations: (layers,) codes; weight_offsets and
    bias_offsets: (layers,) positions in the flat parameter vector, which holds W_0 (row-major,
    (out, in)), b_0, W_1, b_1, ... in the order of `parameters`.  scale is dK_ref for the MLP kernel
    and the geometry factor F otherwise.
    """

    kind: int
    scale: float
    input_lo: np.ndarray  # (2,) stress range MPa, crack length m
    input_span: np.ndarray  # (2,)
    sizes: np.ndarray
    activations: np.ndarray
    weight_offsets: np.ndarray
    bias_offsets: np.ndarray
    parameter_count: int


def unsupported_reason(kernel: DamageKernel, stress_range_mpa: Tensor) -> str | None:
    """Why the fast march cannot run this kernel on these inputs, or None when it can."""
    if type(kernel) not in _KIND_CODES:
        return f"kernel type {type(kernel).__name__} has no compiled march"
    if stress_range_mpa.device.type != "cpu":
        return "the compiled march runs on CPU tensors only"
    if stress_range_mpa.requires_grad:
        return "the compiled march gives no gradient with respect to stress ranges"
    if stress_range_mpa.dtype not in (torch.float32, torch.float64):
        return f"stress ranges must be float32 or float64, got {stress_range_mpa.dtype}"
    if isinstance(kernel, MLPKernel | ResidualKernel):
        unknown = set(kernel.mlp.activations) - set(_ACTIVATION_CODES)
        if unknown:
            return f"activations {sorted(unknown)} have no compiled form"
    return None


def _mlp_layers(kernel: DamageKernel) -> list[tuple[Tensor, Tensor]]:
    if not isinstance(kernel, MLPKernel | ResidualKernel):
        return []
    mlp: MLP = kernel.mlp
    layers: list[tuple[Tensor, Tensor]] = []
    for linear in mlp.linears:
        assert isinstance(linear, torch.nn.Linear)
        layers.append((linear.weight, linear.bias))
    return layers


def pack_kernel(kernel: DamageKernel) -> tuple[PackedKernel, list[Tensor]]:
    """The kernel's structure, and its network parameters in the order of the flat vector."""
    reason = unsupported_reason(kernel, torch.empty(0))
    if reason is not None:
        raise ValueError(f"kernel cannot be packed: {reason}")
    kind = _KIND_CODES[type(kernel)]
    layers = _mlp_layers(kernel)
    sizes, weight_offsets, bias_offsets, parameters = [2], [], [], []
    offset = 0
    for weight, bias in layers:
        sizes.append(weight.shape[0])
        weight_offsets.append(offset)
        bias_offsets.append(offset + weight.numel())
        offset += weight.numel() + bias.numel()
        parameters += [weight, bias]
    if isinstance(kernel, MLPKernel | ResidualKernel):
        activations = [_ACTIVATION_CODES[a] for a in kernel.mlp.activations]
        lo = kernel.input_lo.detach().to(torch.float64).numpy().copy()
        span = kernel.input_span.detach().to(torch.float64).numpy().copy()
    else:
        activations = []
        lo, span = np.zeros(2), np.ones(2)
    if isinstance(kernel, MLPKernel):
        scale = kernel.dk_ref
    else:
        assert isinstance(kernel, PhysicsKernel | ResidualKernel)
        scale = float(kernel.geometry_factor)
    packed = PackedKernel(
        kind=kind,
        scale=float(scale),
        input_lo=lo,
        input_span=span,
        sizes=np.asarray(sizes, dtype=np.int64),
        activations=np.asarray(activations, dtype=np.int64),
        weight_offsets=np.asarray(weight_offsets, dtype=np.int64),
        bias_offsets=np.asarray(bias_offsets, dtype=np.int64),
        parameter_count=offset,
    )
    return packed, parameters


# ---------------------------------------------------------------------------------------------
# Compiled kernels.  Arrays are laid out (flights, aircraft) or (units, aircraft) so that every
# innermost loop runs over aircraft on contiguous memory.


@njit(cache=True)
def _mlp_forward(theta, sizes, activations, w_off, b_off, hidden):
    """Fill hidden[l + 1] (units, aircraft) from hidden[0][:2] (the scaled inputs)."""
    n = hidden.shape[2]
    for layer in range(activations.shape[0]):
        n_in, n_out = sizes[layer], sizes[layer + 1]
        act = activations[layer]
        for j in range(n_out):
            z = hidden[layer + 1, j]
            bias = theta[b_off[layer] + j]
            for i in range(n):
                z[i] = bias
            for k in range(n_in):
                w = theta[w_off[layer] + j * n_in + k]
                x = hidden[layer, k]
                for i in range(n):
                    z[i] += w * x[i]
            if act == 1:
                for i in range(n):
                    z[i] = math.tanh(z[i])
            elif act == 2:
                for i in range(n):
                    if z[i] <= 0.0:
                        z[i] = math.expm1(z[i])


@njit(cache=True)
def _mlp_backward(theta, sizes, activations, w_off, b_off, hidden, grad, grad_next, grad_theta):
    """Back-propagate grad[0] (d loss / d output, per aircraft) through the network.

    Accumulates parameter gradients into grad_theta and returns the buffer that holds
    d loss / d inputs (2, aircraft).
    """
    n = hidden.shape[2]
    for layer in range(activations.shape[0] - 1, -1, -1):
        n_in, n_out = sizes[layer], sizes[layer + 1]
        act = activations[layer]
        for j in range(n_out):
            g = grad[j]
            y = hidden[layer + 1, j]
            if act == 1:
                for i in range(n):
                    g[i] *= 1.0 - y[i] * y[i]
            elif act == 2:
                for i in range(n):
                    if y[i] <= 0.0:
                        g[i] *= y[i] + 1.0
            total = 0.0
            for i in range(n):
                total += g[i]
            grad_theta[b_off[layer] + j] += total
            for k in range(n_in):
                x = hidden[layer, k]
                total = 0.0
                for i in range(n):
                    total += g[i] * x[i]
                grad_theta[w_off[layer] + j * n_in + k] += total
        for k in range(n_in):
            gk = grad_next[k]
            for i in range(n):
                gk[i] = 0.0
            for j in range(n_out):
                w = theta[w_off[layer] + j * n_in + k]
                g = grad[j]
                for i in range(n):
                    gk[i] += w * g[i]
        grad, grad_next = grad_next, grad
    return grad


@njit(cache=True)
def _stress_intensity(
    kind, scale, lo, span, theta, sizes, activations, w_off, b_off, s, a, hidden, dk
):
    """dK (aircraft,) of one flight; leaves the network's activations in hidden."""
    n = a.shape[0]
    if kind == 0:
        for i in range(n):
            dk[i] = scale * s[i] * math.sqrt(math.pi * max(a[i], 0.0))
        return
    x0, x1 = hidden[0, 0], hidden[0, 1]
    for i in range(n):
        x0[i] = (s[i] - lo[0]) / span[0]
        x1[i] = (a[i] - lo[1]) / span[1]
    _mlp_forward(theta, sizes, activations, w_off, b_off, hidden)
    out = hidden[activations.shape[0], 0]
    if kind == 1:
        for i in range(n):
            dk[i] = scale * out[i]
    else:
        for i in range(n):
            dk[i] = scale * s[i] * math.sqrt(math.pi * max(a[i], 0.0)) * (1.0 + out[i])


@njit(cache=True)
def _buffers(sizes, n):
    width = 2
    for k in range(sizes.shape[0]):
        width = max(width, sizes[k])
    return np.zeros((sizes.shape[0], width, n)), np.empty(n)


@njit(cache=True)
def _march_forward(
    stress, lengths, initial, kind, scale, lo, span, theta, sizes, activations, w_off, b_off, c, m
):
    """Trajectory (flights + 1, aircraft) of the Euler recurrence; stress is (flights, aircraft)."""
    steps, n = stress.shape
    traj = np.empty((steps + 1, n))
    traj[0] = initial
    hidden, dk = _buffers(sizes, n)
    for t in range(steps):
        a, a_next = traj[t], traj[t + 1]
        _stress_intensity(
            kind, scale, lo, span, theta, sizes, activations, w_off, b_off, stress[t], a, hidden, dk
        )
        for i in range(n):
            if t < lengths[i] and dk[i] > 0.0:
                a_next[i] = a[i] + c * dk[i] ** m
            else:
                a_next[i] = a[i]
    return traj


@njit(cache=True)
def _march_backward(
    stress,
    lengths,
    traj,
    grad_traj,
    kind,
    scale,
    lo,
    span,
    theta,
    sizes,
    activations,
    w_off,
    b_off,
    c,
    m,
):
    """Adjoint sweep: (d loss / d initial crack (aircraft,), d loss / d theta)."""
    steps, n = stress.shape
    hidden, dk = _buffers(sizes, n)
    grad, grad_next = np.empty((hidden.shape[1], n)), np.empty((hidden.shape[1], n))
    direct = np.empty(n)
    grad_theta = np.zeros(theta.shape[0])
    adjoint = grad_traj[steps].copy()
    for t in range(steps - 1, -1, -1):
        a, s = traj[t], stress[t]
        _stress_intensity(
            kind, scale, lo, span, theta, sizes, activations, w_off, b_off, s, a, hidden, dk
        )
        seed = grad[0]
        for i in range(n):
            rate = 0.0  # lambda_t * d(da_t) / d(dK_t)
            if t < lengths[i] and dk[i] > 0.0:
                rate = adjoint[i] * c * m * dk[i] ** (m - 1.0)
            # d dK / d a through the explicit sqrt(pi a) factor (physics and residual kernels)
            root = 0.0 if kind == 1 or a[i] <= 0.0 else 0.5 * dk[i] / a[i]
            direct[i] = rate * root
            if kind == 1:
                seed[i] = rate * scale
            elif kind == 2:
                seed[i] = rate * scale * s[i] * math.sqrt(math.pi * a[i]) if a[i] > 0.0 else 0.0
        if kind != 0:
            grad_in = _mlp_backward(
                theta, sizes, activations, w_off, b_off, hidden, grad, grad_next, grad_theta
            )
            g1 = grad_in[1]
            for i in range(n):
                direct[i] += g1[i] / span[1]
        for i in range(n):
            adjoint[i] = grad_traj[t, i] + adjoint[i] + direct[i]
    return adjoint, grad_theta


# ---------------------------------------------------------------------------------------------


def _kernel_args(packed: PackedKernel, theta: np.ndarray, law: ParisLaw) -> tuple[Any, ...]:
    return (
        packed.kind,
        packed.scale,
        packed.input_lo,
        packed.input_span,
        theta,
        packed.sizes,
        packed.activations,
        packed.weight_offsets,
        packed.bias_offsets,
        float(law.c),
        float(law.m),
    )


def _flat(parameters: tuple[Tensor, ...]) -> np.ndarray:
    if not parameters:
        return np.zeros(0)
    return torch.cat([p.detach().reshape(-1).to(torch.float64) for p in parameters]).numpy()


class _FastEulerMarch(torch.autograd.Function):
    @staticmethod
    def forward(
        ctx: Any,
        packed: PackedKernel,
        law: ParisLaw,
        stress_range_mpa: Tensor,
        lengths: Tensor,
        initial_crack_m: Tensor,
        *parameters: Tensor,
    ) -> Tensor:
        stress = stress_range_mpa.detach().to(torch.float64).T.contiguous().numpy()
        steps = np.ascontiguousarray(lengths.detach().cpu().numpy(), dtype=np.int64)
        initial = initial_crack_m.detach().to(torch.float64).contiguous().numpy()
        theta = _flat(parameters)
        traj = _march_forward(stress, steps, initial, *_kernel_args(packed, theta, law))
        ctx.packed, ctx.law, ctx.dtype = packed, law, stress_range_mpa.dtype
        ctx.numpy_inputs = (stress, steps, traj, theta)
        ctx.initial_dtype = initial_crack_m.dtype
        ctx.parameter_meta = [(tuple(p.shape), p.dtype) for p in parameters]
        return torch.from_numpy(traj).T.to(stress_range_mpa.dtype).contiguous()

    @staticmethod
    @once_differentiable
    def backward(ctx: Any, grad_trajectory: Tensor) -> tuple[Tensor | None, ...]:
        stress, steps, traj, theta = ctx.numpy_inputs
        grad_traj = grad_trajectory.detach().to(torch.float64).T.contiguous().numpy()
        grad_initial, grad_theta = _march_backward(
            stress, steps, traj, grad_traj, *_kernel_args(ctx.packed, theta, ctx.law)
        )
        grads: list[Tensor | None] = [None, None, None, None]
        grads.append(torch.from_numpy(grad_initial).to(ctx.initial_dtype))
        flat = torch.from_numpy(grad_theta)
        offset = 0
        for shape, dtype in ctx.parameter_meta:
            count = math.prod(shape)
            grads.append(flat[offset : offset + count].reshape(shape).to(dtype))
            offset += count
        return tuple(grads)


def fast_march(
    kernel: DamageKernel,
    law: ParisLaw,
    stress_range_mpa: Tensor,
    lengths: Tensor,
    initial_crack_m: Tensor,
) -> Tensor:
    """Crack length (aircraft, flights + 1) in m from a_t = a_{t-1} + C max(dK(dS_t, a_{t-1}), 0)**m.

    stress_range_mpa: (aircraft, flights) MPa, zero-padded; lengths: (aircraft,) real flights of
    each (later steps keep the crack); initial_crack_m: (aircraft,) m.  Differentiable with
    respect to the kernel's network parameters and the initial crack.  Raises ValueError when
    `unsupported_reason` names a reason.
    """
    reason = unsupported_reason(kernel, stress_range_mpa)
    if reason is not None:
        raise ValueError(f"fast march unavailable: {reason}")
    if initial_crack_m.shape != stress_range_mpa.shape[:1]:
        raise ValueError("initial_crack_m must have one entry per aircraft")
    packed, parameters = pack_kernel(kernel)
    return march_packed(packed, parameters, law, stress_range_mpa, lengths, initial_crack_m)


def march_packed(
    packed: PackedKernel,
    parameters: Sequence[Tensor],
    law: ParisLaw,
    stress_range_mpa: Tensor,
    lengths: Tensor,
    initial_crack_m: Tensor,
) -> Tensor:
    """`fast_march` on a packed kernel whose network weights are given as `parameters`.

    parameters: the tensors `pack_kernel` returned, or replacements of the same shapes (for
    functional use, e.g. gradcheck).  Inputs are not checked here.
    """
    if len(parameters) != len(packed.sizes) * 2 - 2:
        raise ValueError(f"parameters must hold {len(packed.sizes) * 2 - 2} tensors")
    out: Tensor = _FastEulerMarch.apply(
        packed, law, stress_range_mpa, lengths, initial_crack_m, *parameters
    )
    return out
