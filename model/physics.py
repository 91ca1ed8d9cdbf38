"""Physics kernels as plain tensor functions (thesis ch. 3): Paris law and the 2-DOF vibration."""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import Tensor

from model.geometry import GeometryTable
from model.growth_laws import GrowthConstants
from model.nasgro import NasgroTerms

# Paris' law holds up to fracture at a_crit; past it a march's crack means only "failed", and
# it diverges within a few hundred flights.  Marches hold cracks at this multiple of a_crit, so
# that forecasts stay finite (the fleet generator holds its truth at the same).
HELD_CRACK_FACTOR = 10.0
# A measured crack this many a_crit long has run away: it says the tail failed, not how fast it
# grew (a held crack, even 4 sizing sd short, reads longer).  Shorter ones, a_crit included,
# are growth data like any other: the law runs on past a_crit, and leaving them out kept only
# the fast tails whose noise came out short, which bent the learned kernel down at long cracks
# (benchmarks/tracking.py seed 2: its rise -4 % against the truth's +6 %, p95 error 22.9 %).
RUNAWAY_CRACK_FACTOR = 5.0


@dataclass(frozen=True)
class ParisLaw:
    """The fleet's physics, thesis defaults (SI: m, MPa): the growth law's material constants
    (C, m and Walker's gamma, `constants`; gamma is read by the Walker law only, `nasgro` by
    the NASGRO law only) and the geometry (geometry factor F, initial and critical crack),
    which no growth law sees.

    With a `geometry_table` every march takes F at the step's crack from it
    (model.geometry.GeometryTable: linear, held outside the table), the calibration of C and m
    too (model.growth_integral); `geometry_factor` is then F where one constant is all a
    reader can use (the MLP kernel's warm start, the calibration's reference dK), and whoever
    builds the law sets it to the table's value at a0."""

    c: float = 1.5e-11
    m: float = 3.8
    geometry_factor: float = 1.0
    initial_crack_m: float = 0.005
    critical_crack_m: float = 0.05
    gamma: float = 1.0
    geometry_table: GeometryTable | None = None
    nasgro: NasgroTerms | None = None
    # Walker's gamma below R = 0 (None: gamma; model.growth_laws.GrowthConstants)
    gamma_below_zero: float | None = None

    def __post_init__(self) -> None:
        for name in ("c", "m", "geometry_factor", "initial_crack_m", "critical_crack_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if self.critical_crack_m <= self.initial_crack_m:
            raise ValueError("critical_crack_m must exceed initial_crack_m")
        if not 0.0 <= self.gamma <= 1.0:
            raise ValueError(f"gamma must lie in [0, 1], got {self.gamma}")
        below = self.gamma_below_zero
        if below is not None and not 0.0 <= below <= 1.0:
            raise ValueError(f"gamma_below_zero must lie in [0, 1], got {below}")

    @property
    def geometry(self) -> float | GeometryTable:
        """F as the kernels read it: the table where there is one, else the constant."""
        return self.geometry_factor if self.geometry_table is None else self.geometry_table

    @property
    def constants(self) -> GrowthConstants:
        """What a growth law sees: C, m, gamma and the NASGRO terms."""
        return GrowthConstants(self.c, self.m, self.gamma, self.nasgro, self.gamma_below_zero)

    @property
    def held_crack_m(self) -> float:
        """Where marches hold a crack that has run past fracture (HELD_CRACK_FACTOR)."""
        return HELD_CRACK_FACTOR * self.critical_crack_m

    @property
    def runaway_crack_m(self) -> float:
        """Measured cracks at or past this say the crack ran away, not its rate
        (RUNAWAY_CRACK_FACTOR): fits of the growth law leave them out."""
        return RUNAWAY_CRACK_FACTOR * self.critical_crack_m


def stress_intensity_range(
    stress_range_mpa: Tensor,
    crack_length_m: Tensor,
    geometry_factor: float | Tensor | GeometryTable = 1.0,
) -> Tensor:
    """dK = F(a) * dS * sqrt(pi * a), in MPa*sqrt(m); crack lengths below 0 are treated as 0.
    geometry_factor: F, a constant (or per-element tensor) or a table over crack length read at
    each a (model.geometry.GeometryTable)."""
    factor = (
        geometry_factor.at(crack_length_m)
        if isinstance(geometry_factor, GeometryTable)
        else geometry_factor
    )
    return factor * stress_range_mpa * torch.sqrt(math.pi * crack_length_m.clamp_min(0.0))


def paris_law(stress_intensity: Tensor, c: float, m: float) -> Tensor:
    """da/dN = C * dK**m, in m per cycle; a negative dK (only a network can produce one) grows nothing."""
    return c * stress_intensity.clamp_min(0.0) ** m


def paris_growth(stress_intensity: Tensor, law: ParisLaw) -> Tensor:
    """Paris' law with the fleet's constants: da/dN = C * max(dK, 0)**m."""
    return paris_law(stress_intensity, law.c, law.m)


# Growth laws da/dN(dK, flight channels, constants) by name live in model.growth_laws.


def paris_closed_form(
    initial_crack_m: float, stress_range_mpa: float, cycles: Tensor | float, law: ParisLaw
) -> Tensor:
    """Exact crack length after N cycles of constant dS (integrating da/dN = C (F dS sqrt(pi a))**m).

    a(N) = [a0**(1-m/2) + (1-m/2) * C * (F dS sqrt(pi))**m * N] ** (1/(1-m/2)), valid for m != 2
    until the bracket reaches zero (the crack diverges there).
    """
    if law.m == 2:
        raise ValueError("m == 2 has an exponential closed form, not handled here")
    cycles_t = torch.as_tensor(cycles, dtype=torch.float64)
    p = 1.0 - law.m / 2.0
    rate = law.c * (law.geometry_factor * stress_range_mpa * math.sqrt(math.pi)) ** law.m
    return (initial_crack_m**p + p * rate * cycles_t) ** (1.0 / p)


@dataclass(frozen=True)
class TwoDofSystem:
    """Masses (kg), springs (N/m) of the thesis's 2-DOF system; dampers are the unknowns."""

    masses_kg: tuple[float, float] = (20.0, 10.0)
    stiffness_n_per_m: tuple[float, float, float] = (2e3, 1e3, 5e3)


def two_dof_rhs(state: Tensor, force_n: Tensor, damping: Tensor, system: TwoDofSystem) -> Tensor:
    """First-order form of M y'' + C y' + K y = u (thesis eq. 3.7-3.8).

    state: (..., 4) = [y1, y2, y1', y2'] in m and m/s; force_n: (..., 2); damping: (3,) = c1, c2, c3
    in N*s/m.  Returns d(state)/dt with the same shape as state.
    """
    y1, y2, v1, v2 = state.unbind(-1)
    u1, u2 = force_n.unbind(-1)
    c1, c2, c3 = damping.unbind(-1)
    k1, k2, k3 = system.stiffness_n_per_m
    m1, m2 = system.masses_kg
    acc1 = (u1 - (c1 + c2) * v1 + c2 * v2 - (k1 + k2) * y1 + k2 * y2) / m1
    acc2 = (u2 + c2 * v1 - (c2 + c3) * v2 + k2 * y1 - (k2 + k3) * y2) / m2
    return torch.stack((v1, v2, acc1, acc2), dim=-1)
