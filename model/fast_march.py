"""Fast Euler march of the damage cell: a fused numba kernel with an analytic (adjoint) backward.

The recurrence is the one `EulerDamageCell` steps with `model.integrate.march`:

    a_t = a_{t-1} + f * C * max(dK(dS_t, a_{t-1}), 0)**m      (one step per flight; padded steps keep a)

for the three kernels of `model.cells` (physics, MLP, physics * (1 + MLP)), Paris' growth law,
the Euler step and a per-aircraft growth factor f (default 1).  The sequential march
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
* tanh, expm1 (elu) and pow are inlined, branch-free arithmetic (below), not libm calls: libm's
  are opaque to the vectoriser.  With libm (a first version) a training epoch was 28x faster
  than eager and a forecast 3x; with the inlined versions ~55-60x and ~17-21x (forward ~9 ms,
  backward ~13 ms against ~2 s eager).  They agree with libm to a few ulp.
* Single-threaded: splitting the aircraft over 2 threads (numba prange, one task per chunk of
  aircraft for the whole march) measured 2x slower (18.5 against 8.8 ms for 60 aircraft, 85
  against 42 ms for 300) on the shared machine; see also model/runtime.py.
* The kernels release the GIL (nogil): API threads keep serving while a worker thread trains.
* Arithmetic is float64 inside the kernel whatever the input dtype; float32 inputs get float32
  outputs and gradients (within ~3e-6 of the float32 sequential march over 7,300 flights, which
  carries its own rounding).  One compiled signature per kernel keeps the cached compile short.

Semantics match the torch cells: dK is clamped at 0 before the power (so a negative network
output grows nothing), and the physics dK uses sqrt(pi * max(a, 0)).  Where a = 0 exactly, the
derivative of sqrt(a) is taken as 0 (torch yields nan there).  The gradient flows to the network's
weights and biases, the initial crack and the growth factor; not to the stress ranges (`unsupported_reason` says
so, and the caller falls back to the sequential march).  Gradients are first order only (the
backward is itself not differentiable); higher-order derivatives need the sequential march.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from llvmlite import ir as llvm_ir
from numba import njit
from numba import types as numba_types
from numba.extending import intrinsic
from torch import Tensor
from torch.autograd.function import once_differentiable

from model.cells import (
    EULER,
    DamageCell,
    DamageKernel,
    InputBox,
    MLPKernel,
    PhysicsKernel,
    ResidualKernel,
)
from model.flat import flatten, unflatten
from model.nets import MLP
from model.physics import ParisLaw

_PHYSICS, _MLP, _RESIDUAL = 0, 1, 2
_KIND_CODES: dict[type[DamageKernel], int] = {
    PhysicsKernel: _PHYSICS,
    MLPKernel: _MLP,
    ResidualKernel: _RESIDUAL,
}
_LINEAR, _TANH, _ELU = 0, 1, 2
_ACTIVATION_CODES = {"linear": _LINEAR, "tanh": _TANH, "elu": _ELU}


@dataclass(frozen=True)
class PackedKernel:
    """A damage kernel's structure as flat arrays a compiled march can read.

    sizes: (layers + 1,) layer widths, input first; activations: (layers,) codes; weight_offsets and
    bias_offsets: (layers,) positions in the flat parameter vector, which holds W_0 (row-major,
    (out, in)), b_0, W_1, b_1, ... in the order `pack_kernel` returns the parameters.  scale is
    dK_ref for the MLP kernel and the geometry factor F otherwise.
    """

    kind: int
    scale: float
    input_lo: np.ndarray  # (2,) stress range MPa, crack length m
    input_span: np.ndarray  # (2,)
    sizes: np.ndarray
    activations: np.ndarray
    weight_offsets: np.ndarray
    bias_offsets: np.ndarray


def unsupported_reason(cell: DamageCell, stress_range_mpa: Tensor) -> str | None:
    """Why the fast march cannot run this cell (kernel, growth law, step) on these inputs, or
    None when it can.  The kernel's exact class counts: a subclass may compute something else."""
    kernel = cell.kernel
    if type(kernel) not in _KIND_CODES:
        return f"kernel type {type(kernel).__name__} has no compiled march"
    if cell.growth_law != "paris":
        return f"growth law {cell.growth_law!r} has no compiled march"
    if cell.tableau != EULER:
        return "the compiled march steps with forward Euler only"
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
    if type(kernel) not in _KIND_CODES:
        raise ValueError(f"kernel cannot be packed: {type(kernel).__name__} has no compiled form")
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
        unknown = set(kernel.mlp.activations) - set(_ACTIVATION_CODES)
        if unknown:
            raise ValueError(f"kernel cannot be packed: activations {sorted(unknown)}")
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
    )
    return packed, parameters


# ---------------------------------------------------------------------------------------------
# Compiled kernels.  Per-flight state is held in (lanes,) and (units, lanes) buffers so that every
# innermost loop runs over aircraft on contiguous memory, and the loop bodies are branch-free so
# LLVM turns them into SIMD code.  libm's tanh, exp and pow are opaque calls that block this
# (tanh alone cost ~30 ns an aircraft-step); the inlined versions below are plain arithmetic.


def _float_bits_typing(typingctx, x):
    """The IEEE-754 bits of a float64 as an int64 (a bit cast, no conversion)."""

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], llvm_ir.IntType(64))

    return numba_types.int64(numba_types.float64), codegen


def _bits_float_typing(typingctx, x):
    """The float64 whose IEEE-754 bits are the int64 x."""

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], llvm_ir.DoubleType())

    return numba_types.float64(numba_types.int64), codegen


# Any: mypy reads an intrinsic's typing signature (typingctx, x) as its call signature.
_float_bits: Any = intrinsic(_float_bits_typing)
_bits_float: Any = intrinsic(_bits_float_typing)


_LOG2_E = 1.4426950408889634
_LN2_HI, _LN2_LO = 6.93147180369123816490e-01, 1.90821492927058770002e-10  # Cody-Waite split
_EXP_OVERFLOW = 709.782712893384  # log(largest float64)


@njit(inline="always", error_model="numpy")
def _exp_parts(x):
    """(s, q) with exp(x) = s * (1 + q), s = 2**k, |q| < 0.42; x is clamped to [-600, 709].

    Keeping q apart gives expm1 without cancellation near 0.  Taylor series to r**13 on
    |r| <= ln(2) / 2: truncation below 1e-16 relative; measured within 3 ulp of libm.  The low
    clamp keeps s * q clear of subnormal floats (each costs a ~100-cycle microcode assist; hit
    by every dK <= 0 step); callers only need exp(x) ~ 0 there (tanh, elu, da of ~1e-260 m).
    """
    x = min(max(x, -600.0), 709.0)
    k = math.floor(x * _LOG2_E + 0.5)
    r = (x - k * _LN2_HI) - k * _LN2_LO
    p = 1.0 / 6227020800.0
    p = p * r + 1.0 / 479001600.0
    p = p * r + 1.0 / 39916800.0
    p = p * r + 1.0 / 3628800.0
    p = p * r + 1.0 / 362880.0
    p = p * r + 1.0 / 40320.0
    p = p * r + 1.0 / 5040.0
    p = p * r + 1.0 / 720.0
    p = p * r + 1.0 / 120.0
    p = p * r + 1.0 / 24.0
    p = p * r + 1.0 / 6.0
    p = p * r + 0.5
    scale = _bits_float((np.int64(k) + 1023) << 52)
    return scale, r + r * r * p


@njit(inline="always", error_model="numpy")
def _expm1(x):
    scale, q = _exp_parts(x)
    return (scale - 1.0) + scale * q


@njit(inline="always", error_model="numpy")
def _tanh(x):
    t = _expm1(-2.0 * abs(x))  # tanh|x| = -t / (2 + t), no cancellation for small |x|
    return math.copysign(-t / (2.0 + t), x)


@njit(inline="always", error_model="numpy")
def _elu(x):
    return x if x > 0.0 else _expm1(min(x, 0.0))


_SQRT_2 = 1.4142135623730951


@njit(inline="always", error_model="numpy")
def _log(x):
    """Natural log of a positive normal float: exponent from the bits, then 2 atanh((u-1)/(u+1))
    for the mantissa u in [sqrt(1/2), sqrt(2)) (series to f**23: truncation below 1e-18)."""
    bits = _float_bits(x)
    exponent = (bits >> 52) - 1023
    mantissa = _bits_float((bits & 0x000FFFFFFFFFFFFF) | 0x3FF0000000000000)
    high = mantissa > _SQRT_2
    mantissa = mantissa * 0.5 if high else mantissa
    e = float(exponent + 1 if high else exponent)
    f = (mantissa - 1.0) / (mantissa + 1.0)
    f2 = f * f
    p = 1.0 / 23.0
    p = p * f2 + 1.0 / 21.0
    p = p * f2 + 1.0 / 19.0
    p = p * f2 + 1.0 / 17.0
    p = p * f2 + 1.0 / 15.0
    p = p * f2 + 1.0 / 13.0
    p = p * f2 + 1.0 / 11.0
    p = p * f2 + 1.0 / 9.0
    p = p * f2 + 1.0 / 7.0
    p = p * f2 + 1.0 / 5.0
    p = p * f2 + 1.0 / 3.0
    return e * _LN2_HI + (2.0 * f + (2.0 * f * f2 * p + e * _LN2_LO))


@njit(inline="always", error_model="numpy")
def _power(x, m):
    """x**m for a positive finite x (relative error ~1e-15 for x**m within 1e+-100)."""
    y = m * _log(x)
    scale, q = _exp_parts(y)
    return math.inf if y > _EXP_OVERFLOW else scale + scale * q


@njit(inline="always", error_model="numpy")
def _paris_growth(dk, c, m):
    """C * max(dK, 0)**m, with torch's results for dK = 0, +-inf and nan."""
    growth = c * _power(max(dk, 1e-300), m)
    growth = growth if dk > 0.0 else 0.0
    return growth if abs(dk) < math.inf else (0.0 if dk < 0.0 else c * dk)


@njit(cache=True, error_model="numpy")
def _mlp_forward(theta, sizes, activations, w_off, b_off, hidden):
    """Fill hidden[l + 1] (units, aircraft) from hidden[0, :2] (the scaled inputs)."""
    n = hidden.shape[2]
    for layer in range(activations.shape[0]):
        n_in, n_out = sizes[layer], sizes[layer + 1]
        act = activations[layer]
        for j in range(n_out):
            bias = theta[b_off[layer] + j]
            for i in range(n):
                hidden[layer + 1, j, i] = bias
            for k in range(n_in):
                w = theta[w_off[layer] + j * n_in + k]
                for i in range(n):
                    hidden[layer + 1, j, i] += w * hidden[layer, k, i]
            if act == _TANH:
                for i in range(n):
                    hidden[layer + 1, j, i] = _tanh(hidden[layer + 1, j, i])
            elif act == _ELU:
                for i in range(n):
                    hidden[layer + 1, j, i] = _elu(hidden[layer + 1, j, i])


@njit(cache=True, error_model="numpy", fastmath={"reassoc"})
def _mlp_backward(theta, sizes, activations, w_off, b_off, hidden, grad, grad_theta):
    """Back-propagate grad[L, 0] (d loss / d output, per aircraft) through the L layers.

    grad (layers + 1, units, aircraft) receives d loss / d hidden of every layer, so that
    grad[0, :2] ends as d loss / d (scaled inputs); parameter gradients, summed over aircraft,
    are added into grad_theta (parameters,).  fastmath "reassoc" lets those sums use SIMD
    partial sums (keeping per-aircraft sums instead needs a (parameters, aircraft) array that
    falls out of cache for the larger networks).
    """
    n = hidden.shape[2]
    for layer in range(activations.shape[0] - 1, -1, -1):
        n_in, n_out = sizes[layer], sizes[layer + 1]
        act = activations[layer]
        for j in range(n_out):
            if act == _TANH:
                for i in range(n):
                    y = hidden[layer + 1, j, i]
                    grad[layer + 1, j, i] *= 1.0 - y * y
            elif act == _ELU:
                for i in range(n):
                    y = hidden[layer + 1, j, i]
                    grad[layer + 1, j, i] *= y + 1.0 if y <= 0.0 else 1.0
            total = 0.0
            for i in range(n):
                total += grad[layer + 1, j, i]
            grad_theta[b_off[layer] + j] += total
            for k in range(n_in):
                total = 0.0
                for i in range(n):
                    total += grad[layer + 1, j, i] * hidden[layer, k, i]
                grad_theta[w_off[layer] + j * n_in + k] += total
        for k in range(n_in):
            for i in range(n):
                grad[layer, k, i] = 0.0
            for j in range(n_out):
                w = theta[w_off[layer] + j * n_in + k]
                for i in range(n):
                    grad[layer, k, i] += w * grad[layer + 1, j, i]


@njit(cache=True, error_model="numpy")
def _stress_intensity(net, s, a, hidden, dk):
    """dK (lanes,) of one flight from s, a (lanes,); leaves the network's activations in hidden.

    net = (kind, scale, input_lo, input_span, theta, sizes, activations, w_off, b_off).
    """
    kind, scale, lo, span, theta, sizes, activations, w_off, b_off = net
    n = a.shape[0]
    if kind == _PHYSICS:
        for i in range(n):
            dk[i] = scale * s[i] * math.sqrt(math.pi * max(a[i], 0.0))
        return
    for i in range(n):
        hidden[0, 0, i] = (s[i] - lo[0]) / span[0]
        hidden[0, 1, i] = (a[i] - lo[1]) / span[1]
    _mlp_forward(theta, sizes, activations, w_off, b_off, hidden)
    out = activations.shape[0]
    if kind == _MLP:
        for i in range(n):
            dk[i] = scale * hidden[out, 0, i]
    else:
        for i in range(n):
            physics = scale * s[i] * math.sqrt(math.pi * max(a[i], 0.0))
            dk[i] = physics * (1.0 + hidden[out, 0, i])


@njit(cache=True, error_model="numpy")
def _buffers(sizes, lanes):
    """Per-step scratch: network activations (layers + 1, widest layer, lanes) and dK (lanes,)."""
    width = 2
    for k in range(sizes.shape[0]):
        width = max(width, sizes[k])
    return np.zeros((sizes.shape[0], width, lanes)), np.zeros(lanes)


@njit(cache=True, error_model="numpy", nogil=True)
def _march_forward(stress, lengths, initial, factor, lanes, net, c, m):
    """Trajectory (aircraft, flights + 1) of the Euler recurrence; stress is (aircraft, flights),
    factor (lanes,) the growth factor of each lane.

    The state lives in contiguous (lanes,) buffers, lanes >= aircraft; the extra lanes carry
    zero stress and are never flown.  Moving one column in and out per flight costs far less than
    transposing the (aircraft, flights) arrays.
    """
    n, steps = stress.shape
    traj = np.empty((n, steps + 1))
    hidden, dk = _buffers(net[5], lanes)
    a, s = np.zeros(lanes), np.zeros(lanes)
    flown = np.zeros(lanes, dtype=np.int64)
    for i in range(n):
        a[i], flown[i], traj[i, 0] = initial[i], lengths[i], initial[i]
    for t in range(steps):
        for i in range(n):
            s[i] = stress[i, t]
        _stress_intensity(net, s, a, hidden, dk)
        for i in range(lanes):
            grown = a[i] + factor[i] * _paris_growth(dk[i], c, m)
            a[i] = grown if t < flown[i] else a[i]
        for i in range(n):
            traj[i, t + 1] = a[i]
    return traj


@njit(cache=True, error_model="numpy", nogil=True)
def _march_backward(stress, lengths, traj, grad_traj, factor, lanes, net, c, m):
    """Adjoint sweep: d loss / d (initial crack (aircraft,), theta, growth factor (aircraft,))."""
    kind, scale, _, span, theta, sizes, activations, w_off, b_off = net
    n, steps = stress.shape
    hidden, dk = _buffers(sizes, lanes)
    grad = np.zeros_like(hidden)
    layers = activations.shape[0]
    a, s, rate, direct = np.zeros(lanes), np.zeros(lanes), np.zeros(lanes), np.zeros(lanes)
    adjoint, grad_factor = np.zeros(lanes), np.zeros(lanes)
    flown = np.zeros(lanes, dtype=np.int64)
    for i in range(n):
        adjoint[i], flown[i] = grad_traj[i, steps], lengths[i]
    grad_theta = np.zeros(theta.shape[0])
    for t in range(steps - 1, -1, -1):
        for i in range(n):
            a[i], s[i] = traj[i, t], stress[i, t]
        _stress_intensity(net, s, a, hidden, dk)
        for i in range(lanes):
            # lambda_t * d(da_t) / d(dK_t), and lambda_t * d(da_t) / d f = lambda_t * C dK**m
            flying = dk[i] > 0.0 and t < flown[i]
            power = factor[i] * c * m * _power(max(dk[i], 1e-300), m - 1.0)
            rate[i] = adjoint[i] * power if flying else 0.0
            grad_factor[i] += adjoint[i] * _paris_growth(dk[i], c, m) if t < flown[i] else 0.0
        if kind == _MLP:
            for i in range(lanes):
                grad[layers, 0, i] = rate[i] * scale
        else:
            # d dK / d a through the explicit sqrt(pi a) factor: dK / (2 a)
            for i in range(lanes):
                direct[i] = rate[i] * (0.5 * dk[i] / a[i] if a[i] > 0.0 else 0.0)
        if kind == _RESIDUAL:
            for i in range(lanes):
                grad[layers, 0, i] = rate[i] * scale * s[i] * math.sqrt(math.pi * max(a[i], 0.0))
        if kind != _PHYSICS:
            _mlp_backward(theta, sizes, activations, w_off, b_off, hidden, grad, grad_theta)
        if kind == _MLP:
            for i in range(lanes):
                adjoint[i] += grad[0, 1, i] / span[1]
        elif kind == _RESIDUAL:
            for i in range(lanes):
                adjoint[i] += direct[i] + grad[0, 1, i] / span[1]
        else:
            for i in range(lanes):
                adjoint[i] += direct[i]
        for i in range(n):
            adjoint[i] += grad_traj[i, t]
    return adjoint[:n].copy(), grad_theta, grad_factor[:n].copy()


# ---------------------------------------------------------------------------------------------


def _network(packed: PackedKernel, theta: np.ndarray) -> tuple[Any, ...]:
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
    )


def _float64_array(values: Tensor) -> np.ndarray:
    """A C-contiguous float64 view of values (a copy only where dtype or layout differ)."""
    return values.detach().to(torch.float64).contiguous().numpy()


# The compiled loops run over this many lanes: the aircraft rounded up to a multiple of 32, so
# that the SIMD loops (8 doubles per AVX-512 register, unrolled 4x by LLVM) never fall into
# their scalar remainder.  With 60 aircraft that remainder alone took about half the time.
_LANES = 32


class _FastEulerMarch(torch.autograd.Function):
    @staticmethod
    def forward(
        ctx: Any,
        packed: PackedKernel,
        law: ParisLaw,
        stress_range_mpa: Tensor,
        lengths: Tensor,
        initial_crack_m: Tensor,
        growth_factor: Tensor,
        *parameters: Tensor,
    ) -> Tensor:
        aircraft = stress_range_mpa.shape[0]
        lanes = -(-aircraft // _LANES) * _LANES
        stress = _float64_array(stress_range_mpa)  # (aircraft, flights)
        flown = lengths.detach().cpu().to(torch.int64).contiguous().numpy()
        factor = np.ones(lanes)
        factor[:aircraft] = _float64_array(growth_factor)
        net = _network(packed, flatten(parameters).numpy())
        c, m = float(law.c), float(law.m)
        traj = _march_forward(
            stress, flown, _float64_array(initial_crack_m), factor, lanes, net, c, m
        )
        ctx.march = (stress, flown, traj, factor, lanes, net, c, m)
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
        stress, flown, traj, factor, lanes, net, c, m = ctx.march
        grad_initial, grad_theta, grad_factor = _march_backward(
            stress, flown, traj, _float64_array(grad_trajectory), factor, lanes, net, c, m
        )
        initial_dtype, factor_dtype = ctx.dtypes
        grads = unflatten(torch.from_numpy(grad_theta), ctx.parameters)
        return (
            None,
            None,
            None,
            None,
            torch.from_numpy(grad_initial).to(initial_dtype),
            torch.from_numpy(grad_factor).to(factor_dtype),
            *(g.to(p.dtype) for g, p in zip(grads, ctx.parameters, strict=True)),
        )


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
    if growth_factor is None:
        growth_factor = torch.ones_like(initial_crack_m)
    packed, parameters = pack_kernel(cell.kernel)
    out: Tensor = _FastEulerMarch.apply(
        packed, cell.law, stress_range_mpa, lengths, initial_crack_m, growth_factor, *parameters
    )
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
