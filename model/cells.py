"""Recurrent cells: what changes in one step.

Three roles, as for any ODE (STYLE.md): the **term** (a right-hand side: the crack growth rate
da/dN = f * law(kernel(dS, a)) from a stress-intensity kernel, a growth law and a per-aircraft
growth factor f; or the 2-DOF dynamics), the **step** (an explicit Runge-Kutta method held as
data, `ButcherTableau`; Euler per flight by default) and the **march** (model.integrate, or the
compiled model.fast_march).  Kernels, growth laws and steps are registries read by the model
spec, the schemas, the command line and the model files: a new kernel is a subclass with a
`name`, a new law a subclass in model.growth_laws, a new solver one tableau in STEPS.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import ClassVar

import torch
from torch import Tensor, nn

from model.geometry import GeometryTable
from model.growth_laws import GROWTH_LAWS
from model.nets import MLP
from model.physics import (
    ParisLaw,
    TwoDofSystem,
    stress_intensity_range,
    two_dof_rhs,
)


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


KERNELS: dict[str, type[DamageKernel]] = {}


class DamageKernel(nn.Module):
    """Stress-intensity range dK (MPa*sqrt(m)) from stress range dS (MPa) and crack length a (m).

    A subclass with a `name` registers itself in KERNELS; `from_spec` builds it from the model
    spec's parts, `learned` says whether it holds a network (and so needs an input box).
    """

    name: ClassVar[str] = ""
    learned: ClassVar[bool] = True

    def __init_subclass__(cls, **kwargs: object) -> None:
        super().__init_subclass__(**kwargs)
        if "name" in cls.__dict__ and cls.name:  # a subclass that names itself, not its parent
            if cls.name in KERNELS:
                raise ValueError(f"kernel {cls.name!r} is registered twice")
            KERNELS[cls.name] = cls

    @classmethod
    def from_spec(
        cls, hidden: Sequence[tuple[int, str]], box: InputBox | None, law: ParisLaw
    ) -> DamageKernel:
        raise NotImplementedError

    def forward(self, stress_range_mpa: Tensor, crack_length_m: Tensor) -> Tensor:
        raise NotImplementedError


class PhysicsKernel(DamageKernel):
    """dK = F(a) * dS * sqrt(pi * a): F a constant or a table over crack length."""

    name = "physics"
    learned = False

    def __init__(self, geometry_factor: float | GeometryTable = 1.0) -> None:
        super().__init__()
        self.geometry_factor = geometry_factor

    @classmethod
    def from_spec(
        cls, hidden: Sequence[tuple[int, str]], box: InputBox | None, law: ParisLaw
    ) -> DamageKernel:
        return cls(law.geometry)

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

    name = "mlp"

    def __init__(self, hidden: Sequence[tuple[int, str]], box: InputBox) -> None:
        super().__init__(hidden, box)
        s_hi, a_hi = box.stress_range_mpa[1], box.crack_length_m[1]
        self.dk_ref = float(stress_intensity_range(torch.tensor(s_hi), torch.tensor(a_hi)))

    @classmethod
    def from_spec(
        cls, hidden: Sequence[tuple[int, str]], box: InputBox | None, law: ParisLaw
    ) -> DamageKernel:
        assert box is not None
        return cls(hidden, box)

    def forward(self, stress_range_mpa: Tensor, crack_length_m: Tensor) -> Tensor:
        return self.dk_ref * self.mlp(self.scaled_inputs(stress_range_mpa, crack_length_m))


class ResidualKernel(_ScaledMLPKernel):
    """Physics corrected by a network: dK = F(a) * dS * sqrt(pi * a) * (1 + MLP(scale(dS, a))),
    F a constant or a table over crack length (the network corrects what the table misses).

    Starts at the physics (zero MLP output) and keeps it where data are missing, so it
    extrapolates beyond the inspected crack range far better than an MLP that replaces dK.
    Outside the input box the correction is held at the box's edge: the physics alone carries
    the shape there (an MLP's own extrapolation past a_crit ran cracks away 2-3x too fast).
    """

    name = "residual"

    def __init__(
        self,
        hidden: Sequence[tuple[int, str]],
        box: InputBox,
        geometry_factor: float | GeometryTable = 1.0,
    ) -> None:
        super().__init__(hidden, box)
        self.geometry_factor = geometry_factor
        self.mlp.zero_output()

    @classmethod
    def from_spec(
        cls, hidden: Sequence[tuple[int, str]], box: InputBox | None, law: ParisLaw
    ) -> DamageKernel:
        assert box is not None
        return cls(hidden, box, law.geometry)

    def forward(self, stress_range_mpa: Tensor, crack_length_m: Tensor) -> Tensor:
        physics = stress_intensity_range(stress_range_mpa, crack_length_m, self.geometry_factor)
        inputs = self.scaled_inputs(stress_range_mpa, crack_length_m).clamp(0.0, 1.0)
        return physics * (1.0 + self.mlp(inputs))


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


STEPS: dict[str, ButcherTableau] = {"euler": EULER, "midpoint": MIDPOINT, "rk4": RK4}


def explicit_step(
    rhs: Callable[[Tensor], Tensor], state: Tensor, step: float, tableau: ButcherTableau
) -> Tensor:
    """One explicit Runge-Kutta step of dx/dt = rhs(x) (inputs held over the step).

    y_{n+1} = y_n + h * sum_i b_i k_i,  k_i = rhs(y_n + h * sum_j a_ij k_j).
    """
    slopes: list[Tensor] = []
    for i in range(len(tableau.b)):
        stage = state
        for j in range(i):
            if tableau.a[i][j] != 0:
                stage = stage + (step * tableau.a[i][j]) * slopes[j]
        slopes.append(rhs(stage))
    increment = sum(
        (w * k for w, k in zip(tableau.b, slopes, strict=True) if w != 0), torch.zeros_like(state)
    )
    return state + step * increment


class DamageCell(nn.Module):
    """One flight (dN = 1 cycle) of da/dN = f * law(kernel(dS, a)), stepped by `tableau`.

    The term: a kernel gives dK, the growth law (model.growth_laws.GROWTH_LAWS, Paris by
    default) gives da/dN = C * dK**m from dK and its constants (C, m, gamma: never the
    critical crack), and f, a per-aircraft growth factor (default 1), scales it: the
    tail-to-tail scatter of growth rate that replicate tests show.  With Euler this is the
    thesis's a_t = a_{t-1} + f * C * dK_t**m.
    """

    def __init__(
        self,
        kernel: DamageKernel,
        law: ParisLaw,
        growth_law: str = "paris",
        tableau: ButcherTableau = EULER,
    ) -> None:
        super().__init__()
        if growth_law not in GROWTH_LAWS:
            raise ValueError(f"growth_law must be one of {sorted(GROWTH_LAWS)}, got {growth_law!r}")
        self.kernel, self.law, self.growth_law, self.tableau = kernel, law, growth_law, tableau

    def rate(
        self, crack_length_m: Tensor, stress_range_mpa: Tensor, growth_factor: Tensor | None = None
    ) -> Tensor:
        """da/dN (batch,) in m per cycle of the flight's (damage-equivalent) range: its load
        ratios are already in that range (model.growth_laws), so the law sees no other channel."""
        growth = GROWTH_LAWS[self.growth_law](
            self.kernel(stress_range_mpa, crack_length_m), {}, self.law.constants
        )
        return growth if growth_factor is None else growth * growth_factor

    def forward(
        self, crack_length_m: Tensor, stress_range_mpa: Tensor, growth_factor: Tensor | None = None
    ) -> Tensor:  # (batch,): held at the law's held crack past fracture (model.physics)
        grown = explicit_step(
            lambda a: self.rate(a, stress_range_mpa, growth_factor),
            crack_length_m,
            1.0,
            self.tableau,
        )
        held = self.law.held_crack_m
        return grown.nan_to_num(nan=held).clamp_max(held)  # nan: weights that blow up


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
        return explicit_step(lambda x: self.rhs(x, inputs), state, self.step_s, self.tableau)


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
