"""A damage kernel as flat arrays for the compiled march (model/fast_march.py), and which cells
that march can run.

numba's compiled loops read no torch modules: the kernel's kind, scale, input box and layer
layout travel as integers and arrays, its weights and biases as one flat vector.  The codes
below are that format's vocabulary, shared with model/fast_march_loops.py.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from model.cells import (
    EULER,
    DamageCell,
    DamageKernel,
    MLPKernel,
    PhysicsKernel,
    ResidualKernel,
)
from model.geometry import GeometryTable
from model.nets import MLP

# Laws the compiled march steps: C dK**m (Walker's load ratios are folded into the flight's
# input, the damage-equivalent range, model.growth_laws) and the NASGRO equation at R = 0.
COMPILED_LAWS = ("paris", "walker", "nasgro")
KIND_PHYSICS, KIND_MLP, KIND_RESIDUAL = 0, 1, 2
_KIND_CODES: dict[type[DamageKernel], int] = {
    PhysicsKernel: KIND_PHYSICS,
    MLPKernel: KIND_MLP,
    ResidualKernel: KIND_RESIDUAL,
}
ACTIVATION_LINEAR, ACTIVATION_TANH, ACTIVATION_ELU = 0, 1, 2
_ACTIVATION_CODES = {"linear": ACTIVATION_LINEAR, "tanh": ACTIVATION_TANH, "elu": ACTIVATION_ELU}


@dataclass(frozen=True)
class PackedKernel:
    """A damage kernel's structure as flat arrays a compiled march can read.

    sizes: (layers + 1,) layer widths, input first; activations: (layers,) codes; weight_offsets and
    bias_offsets: (layers,) positions in the flat parameter vector, which holds W_0 (row-major,
    (out, in)), b_0, W_1, b_1, ... in the order `pack_kernel` returns the parameters.  scale is
    dK_ref for the MLP kernel and the geometry factor F otherwise (a table's first value).
    A geometry table (model.geometry.GeometryTable) travels as its points and segment slopes,
    F(a) = scale + sum_k slope_k (clamp(a, knot_k, knot_k+1) - knot_k); both are empty for a
    constant F, which the loops take as before.
    """

    kind: int
    scale: float
    input_lo: np.ndarray  # (2,) stress range MPa, crack length m
    input_span: np.ndarray  # (2,)
    sizes: np.ndarray
    activations: np.ndarray
    weight_offsets: np.ndarray
    bias_offsets: np.ndarray
    geometry_knots: np.ndarray  # (points,) crack length m; empty: F = scale
    geometry_slopes: np.ndarray  # (points - 1,) dF/da per m


def _kernel_problem(kernel: DamageKernel) -> str | None:
    """Why the kernel has no compiled form, or None.  The exact class counts: a subclass may
    compute something else."""
    if type(kernel) not in _KIND_CODES:
        return f"kernel type {type(kernel).__name__} has no compiled march"
    if isinstance(kernel, MLPKernel | ResidualKernel):
        unknown = set(kernel.mlp.activations) - set(_ACTIVATION_CODES)
        if unknown:
            return f"activations {sorted(unknown)} have no compiled form"
    return None


def unsupported_reason(cell: DamageCell, stress_range_mpa: Tensor) -> str | None:
    """Why the fast march cannot run this cell (kernel, growth law, step) on these inputs, or
    None when it can."""
    problem = _kernel_problem(cell.kernel)
    if problem is not None:
        return problem
    if cell.growth_law not in COMPILED_LAWS:
        return f"growth law {cell.growth_law!r} has no compiled march"
    if cell.tableau != EULER:
        return "the compiled march steps with forward Euler only"
    if stress_range_mpa.device.type != "cpu":
        return "the compiled march runs on CPU tensors only"
    if stress_range_mpa.requires_grad:
        return "the compiled march gives no gradient with respect to stress ranges"
    if stress_range_mpa.dtype not in (torch.float32, torch.float64):
        return f"stress ranges must be float32 or float64, got {stress_range_mpa.dtype}"
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
    """The kernel's structure, and its network parameters in the order of the flat vector.
    Raises ValueError for a kernel without a compiled form."""
    problem = _kernel_problem(kernel)
    if problem is not None:
        raise ValueError(f"kernel cannot be packed: {problem}")
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
    knots, slopes = np.zeros(0), np.zeros(0)
    if isinstance(kernel, MLPKernel):
        scale = kernel.dk_ref
    else:
        assert isinstance(kernel, PhysicsKernel | ResidualKernel)
        geometry = kernel.geometry_factor
        if isinstance(geometry, GeometryTable):
            scale = geometry.factor[0]
            knots = np.asarray(geometry.crack_length_m, dtype=np.float64)
            slopes = geometry.slopes()
        else:
            scale = float(geometry)
    packed = PackedKernel(
        kind=_KIND_CODES[type(kernel)],
        scale=float(scale),
        input_lo=lo,
        input_span=span,
        sizes=np.asarray(sizes, dtype=np.int64),
        activations=np.asarray(activations, dtype=np.int64),
        weight_offsets=np.asarray(weight_offsets, dtype=np.int64),
        bias_offsets=np.asarray(bias_offsets, dtype=np.int64),
        geometry_knots=knots,
        geometry_slopes=np.ascontiguousarray(slopes, dtype=np.float64),
    )
    return packed, parameters
