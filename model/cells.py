"""Recurrent cells: what changes in one step.

The Euler cumulative-damage cell takes any stress-intensity kernel (physics, MLP, or physics
corrected by an MLP) and keeps the Paris layer as physics.  The Runge-Kutta cell integrates a
first-order system whose right-hand side may hold learnable parameters; the method is data.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch
from torch import Tensor, nn

from model.nets import MLP
from model.physics import ParisLaw, TwoDofSystem, paris_law, stress_intensity_range, two_dof_rhs


@dataclass(frozen=True)
class InputBox:
    """Ranges mapped to [0, 1] before a network sees (stress range, crack length)."""

    stress_range_mpa: tuple[float, float]
    crack_length_m: tuple[float, float]

    def __post_init__(self) -> None:
        for name in ("stress_range_mpa", "crack_length_m"):
            lo, hi = getattr(self, name)
            if not hi > lo:
                raise ValueError(f"{name} must be (low, high) with high > low, got {(lo, hi)}")


class DamageKernel(nn.Module):
    """Stress-intensity range dK (MPa*sqrt(m)) from stress range dS (MPa) and crack length a (m)."""

    kind: str = "abstract"

    def forward(self, stress_range_mpa: Tensor, crack_length_m: Tensor) -> Tensor:
        raise NotImplementedError


class PhysicsKernel(DamageKernel):
    """dK = F * dS * sqrt(pi * a)."""

    kind = "physics"

    def __init__(self, geometry_factor: float = 1.0) -> None:
        super().__init__()
        self.geometry_factor = geometry_factor

    def forward(self, stress_range_mpa: Tensor, crack_length_m: Tensor) -> Tensor:
        return stress_intensity_range(stress_range_mpa, crack_length_m, self.geometry_factor)


class _ScaledMLPKernel(DamageKernel):
    """Shared part of the learned kernels: an MLP on inputs scaled to [0, 1] over `box`."""

    input_lo: Tensor
    input_span: Tensor

    def __init__(self, hidden: Sequence[tuple[int, str]], box: InputBox) -> None:
        super().__init__()
        self.mlp = MLP(hidden, in_features=2)
        self.box = box
        (s_lo, s_hi), (a_lo, a_hi) = box.stress_range_mpa, box.crack_length_m
        self.register_buffer("input_lo", torch.tensor([s_lo, a_lo], dtype=torch.float64))
        self.register_buffer(
            "input_span", torch.tensor([s_hi - s_lo, a_hi - a_lo], dtype=torch.float64)
        )

    def scaled_inputs(self, stress_range_mpa: Tensor, crack_length_m: Tensor) -> Tensor:
        x = torch.stack((stress_range_mpa, crack_length_m), dim=-1)  # (..., 2)
        lo, span = self.input_lo.to(x.dtype), self.input_span.to(x.dtype)
        return (x - lo) / span


class MLPKernel(_ScaledMLPKernel):
    """Thesis hybrid cell: dK = dK_ref * MLP(scale(dS, a)); the MLP replaces the physics of dK.

    dK_ref (physics dK at the box's upper corner) only keeps the MLP's output near unit scale.
    """

    kind = "mlp"

    def __init__(self, hidden: Sequence[tuple[int, str]], box: InputBox) -> None:
        super().__init__(hidden, box)
        s_hi, a_hi = box.stress_range_mpa[1], box.crack_length_m[1]
        self.dk_ref = float(stress_intensity_range(torch.tensor(s_hi), torch.tensor(a_hi)))

    def forward(self, stress_range_mpa: Tensor, crack_length_m: Tensor) -> Tensor:
        return self.dk_ref * self.mlp(self.scaled_inputs(stress_range_mpa, crack_length_m))


class ResidualKernel(_ScaledMLPKernel):
    """Physics corrected by a network: dK = F * dS * sqrt(pi * a) * (1 + MLP(scale(dS, a))).

    Starts at the physics (zero MLP output) and keeps it where data are missing, so it
    extrapolates beyond the inspected crack range far better than an MLP that replaces dK.
    """

    kind = "residual"

    def __init__(
        self, hidden: Sequence[tuple[int, str]], box: InputBox, geometry_factor: float = 1.0
    ) -> None:
        super().__init__(hidden, box)
        self.geometry_factor = geometry_factor
        self.mlp.zero_output()

    def forward(self, stress_range_mpa: Tensor, crack_length_m: Tensor) -> Tensor:
        physics = stress_intensity_range(stress_range_mpa, crack_length_m, self.geometry_factor)
        return physics * (1.0 + self.mlp(self.scaled_inputs(stress_range_mpa, crack_length_m)))


class EulerDamageCell(nn.Module):
    """One flight of forward Euler on Paris' law: a_t = a_{t-1} + C * dK_t**m (dN = 1 cycle)."""

    def __init__(self, kernel: DamageKernel, law: ParisLaw) -> None:
        super().__init__()
        self.kernel = kernel
        self.law = law

    def forward(self, crack_length_m: Tensor, stress_range_mpa: Tensor) -> Tensor:  # (batch,)
        dk = self.kernel(stress_range_mpa, crack_length_m)
        return crack_length_m + paris_law(dk, self.law.c, self.law.m)


@dataclass(frozen=True)
class ButcherTableau:
    """An explicit Runge-Kutta method as data: stage matrix a (lower triangular), weights b, nodes c."""

    a: tuple[tuple[float, ...], ...]
    b: tuple[float, ...]
    c: tuple[float, ...]
    order: int

    def __post_init__(self) -> None:
        stages = len(self.b)
        if len(self.a) != stages or len(self.c) != stages:
            raise ValueError("a, b and c must have one entry per stage")
        for i, row in enumerate(self.a):
            if len(row) != stages or any(row[j] != 0 for j in range(i, stages)):
                raise ValueError("a must be square and strictly lower triangular (explicit method)")
        if abs(sum(self.b) - 1.0) > 1e-12:
            raise ValueError("weights b must sum to 1")


EULER = ButcherTableau(a=((0.0,),), b=(1.0,), c=(0.0,), order=1)
MIDPOINT = ButcherTableau(a=((0.0, 0.0), (0.5, 0.0)), b=(0.0, 1.0), c=(0.0, 0.5), order=2)
RK4 = ButcherTableau(
    a=((0.0, 0.0, 0.0, 0.0), (0.5, 0.0, 0.0, 0.0), (0.0, 0.5, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0)),
    b=(1 / 6, 1 / 3, 1 / 3, 1 / 6),
    c=(0.0, 0.5, 0.5, 1.0),
    order=4,
)


class RungeKuttaCell(nn.Module):
    """One explicit Runge-Kutta step of dx/dt = f(x, u) with the input u held over the step.

    y_{n+1} = y_n + h * sum_i b_i k_i,  k_i = f(y_n + h * sum_j a_ij k_j, u_n).
    """

    def __init__(self, rhs: nn.Module, step_s: float, tableau: ButcherTableau = RK4) -> None:
        super().__init__()
        if not step_s > 0:
            raise ValueError(f"step_s must be > 0, got {step_s}")
        self.rhs, self.step_s, self.tableau = rhs, step_s, tableau

    def forward(self, state: Tensor, inputs: Tensor) -> Tensor:
        h, tab = self.step_s, self.tableau
        slopes: list[Tensor] = []
        for i in range(len(tab.b)):
            stage = state
            for j in range(i):
                if tab.a[i][j] != 0:
                    stage = stage + (h * tab.a[i][j]) * slopes[j]
            slopes.append(self.rhs(stage, inputs))
        increment = sum(
            (w * k for w, k in zip(tab.b, slopes, strict=True) if w != 0), torch.zeros_like(state)
        )
        return state + h * increment


class TwoDofDynamics(nn.Module):
    """2-DOF right-hand side with the three damping coefficients (N*s/m) as learnable parameters."""

    def __init__(self, damping: Sequence[float], system: TwoDofSystem | None = None) -> None:
        super().__init__()
        if len(damping) != 3:
            raise ValueError(f"damping must hold c1, c2, c3, got {len(damping)} values")
        self.system = system or TwoDofSystem()
        self.damping = nn.Parameter(torch.tensor([float(c) for c in damping], dtype=torch.float64))

    def forward(self, state: Tensor, force_n: Tensor) -> Tensor:
        return two_dof_rhs(state, force_n, self.damping.to(state.dtype), self.system)
