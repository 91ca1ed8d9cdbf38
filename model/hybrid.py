"""The crack-growth model the service trains and serves: an Euler damage cell with a chosen kernel."""

from __future__ import annotations

from dataclasses import dataclass, field

import torch
from torch import Tensor, nn

from model.cells import (
    DamageKernel,
    EulerDamageCell,
    InputBox,
    MLPKernel,
    PhysicsKernel,
    ResidualKernel,
)
from model.fast_march import fast_march, unsupported_reason
from model.integrate import LoadHistory, Observations, at_flights, march
from model.nets import THESIS_MLPS, validate_hidden
from model.physics import ParisLaw

KERNELS = ("physics", "mlp", "residual")
MARCH_METHODS = ("auto", "fast", "sequential")


@dataclass(frozen=True)
class ModelSpec:
    """Everything needed to rebuild a crack model (weights aside).

    kernel: "physics" (Paris law alone), "mlp" (thesis hybrid: MLP replaces dK) or "residual"
    (dK = F dS sqrt(pi a) (1 + MLP)).  box: the input ranges scaled to [0, 1] for the network.
    """

    kernel: str = "residual"
    hidden: tuple[tuple[int, str], ...] = THESIS_MLPS[1]
    law: ParisLaw = field(default_factory=ParisLaw)
    box: InputBox | None = None

    def __post_init__(self) -> None:
        if self.kernel not in KERNELS:
            raise ValueError(f"kernel must be one of {KERNELS}, got {self.kernel!r}")
        object.__setattr__(self, "hidden", validate_hidden(self.hidden))
        if self.kernel != "physics" and self.box is None:
            raise ValueError(f"kernel {self.kernel!r} needs an input box")


def default_box(stress_range_mpa: Tensor, law: ParisLaw) -> InputBox:
    """Scale stress over the flown range and cracks over [a0, a_crit], the range a forecast needs."""
    flown = stress_range_mpa[stress_range_mpa > 0]
    if flown.numel() == 0:
        raise ValueError("stress_range_mpa holds no flight with a positive stress range")
    lo, hi = float(flown.min()), float(flown.max())
    if hi - lo < 1e-6 * max(hi, 1.0):
        lo, hi = 0.9 * lo, 1.1 * hi  # one load level: keep a non-empty box around it
    return InputBox((lo, hi), (law.initial_crack_m, law.critical_crack_m))


def build_kernel(spec: ModelSpec) -> DamageKernel:
    if spec.kernel == "physics":
        return PhysicsKernel(spec.law.geometry_factor)
    assert spec.box is not None
    if spec.kernel == "mlp":
        return MLPKernel(spec.hidden, spec.box)
    return ResidualKernel(spec.hidden, spec.box, spec.law.geometry_factor)


class CrackGrowthModel(nn.Module):
    """Crack length of each aircraft after every flight, from its stress-range history."""

    def __init__(self, spec: ModelSpec) -> None:
        super().__init__()
        self.spec = spec
        self.cell = EulerDamageCell(build_kernel(spec), spec.law)
        self.double()

    @property
    def kernel(self) -> DamageKernel:
        return self.cell.kernel

    def trajectory(
        self, loads: LoadHistory, initial_crack_m: Tensor | None = None, *, method: str = "auto"
    ) -> Tensor:
        """Crack length (aircraft, flights + 1) in m; index k is the crack after k flights.

        initial_crack_m: (aircraft,) start of each march; default the loads' own initial cracks,
        else the law's a0.  method: "fast" (compiled march with an adjoint backward, model/fast_march.py),
        "sequential" (the reference loop, autograd through every step) or "auto" (fast whenever
        the kernel and inputs allow it, else sequential).  Raises ValueError for an unknown
        method, or for "fast" where the compiled march cannot run.
        """
        if method not in MARCH_METHODS:
            raise ValueError(f"method must be one of {MARCH_METHODS}, got {method!r}")
        stress = loads.stress_range_mpa
        if initial_crack_m is None:
            initial_crack_m = loads.initial_or(self.spec.law.initial_crack_m)
        initial_crack_m = initial_crack_m.to(stress.dtype)
        if method == "fast" or (
            method == "auto" and unsupported_reason(self.kernel, stress) is None
        ):
            return fast_march(self.kernel, self.cell.law, stress, loads.lengths, initial_crack_m)
        return march(self.cell, stress, initial_crack_m, loads.mask)

    def final_crack(self, loads: LoadHistory) -> Tensor:
        """Crack length (aircraft,) after each aircraft's last recorded flight."""
        traj = self.trajectory(loads)
        return traj[torch.arange(traj.shape[0]), loads.lengths]

    def at(self, loads: LoadHistory, observations: Observations) -> Tensor:
        """Predicted crack length at each observation."""
        return at_flights(self.trajectory(loads), observations)
