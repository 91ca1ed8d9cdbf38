"""The crack-growth model the service trains and serves: a damage cell (kernel, growth law, step)
and its march over each aircraft's flights."""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import torch
from torch import Tensor, nn
from torch.func import functional_call

from model.cells import KERNELS, STEPS, DamageCell, DamageKernel, InputBox
from model.extrapolation import Extrapolation
from model.fast_march import fast_march, fast_march_at, fast_march_points, unsupported_reason
from model.flat import unflatten
from model.growth_laws import GROWTH_LAWS
from model.integrate import LoadHistory, Observations, at_flights, march
from model.nets import MLP, THESIS_MLPS, validate_hidden
from model.physics import ParisLaw

MARCH_METHODS = ("auto", "fast", "sequential")


def kernel_names() -> tuple[str, ...]:
    """Registered damage kernels (model.cells.KERNELS), for schemas, settings and the CLI."""
    return tuple(KERNELS)


@dataclass(frozen=True)
class ModelSpec:
    """Everything needed to rebuild a crack model (weights aside).

    kernel: a name in model.cells.KERNELS: "physics" (Paris law alone), "mlp" (thesis hybrid:
    MLP replaces dK) or "residual" (dK = F dS sqrt(pi a) (1 + MLP)).  growth_law: a name in
    model.physics.GROWTH_LAWS; step: a name in model.cells.STEPS (one step per flight).
    box: the input ranges scaled to [0, 1] for a learned kernel's network.  extrapolation:
    the geometry factor's unknown trend beyond the measured cracks, which every sampled
    forecast draws (model.extrapolation; None: none, as for models fitted before it).
    path_sd: how far each tail's forecast drifts beyond its latest measurement
    (model.path_drift; estimated by model.path_variability; 0: none).
    """

    kernel: str = "residual"
    hidden: tuple[tuple[int, str], ...] = THESIS_MLPS[1]
    law: ParisLaw = field(default_factory=ParisLaw)
    box: InputBox | None = None
    growth_law: str = "paris"
    step: str = "euler"
    extrapolation: Extrapolation | None = None
    path_sd: float = 0.0

    def __post_init__(self) -> None:
        if self.kernel not in KERNELS:
            raise ValueError(f"kernel must be one of {kernel_names()}, got {self.kernel!r}")
        if self.growth_law not in GROWTH_LAWS:
            raise ValueError(
                f"growth_law must be one of {tuple(GROWTH_LAWS)}, got {self.growth_law!r}"
            )
        GROWTH_LAWS[self.growth_law].check(self.law.constants)
        if self.step not in STEPS:
            raise ValueError(f"step must be one of {tuple(STEPS)}, got {self.step!r}")
        object.__setattr__(self, "hidden", validate_hidden(self.hidden))
        if KERNELS[self.kernel].learned and self.box is None:
            raise ValueError(f"kernel {self.kernel!r} needs an input box")

    @property
    def measured_up_to_m(self) -> float:
        """The longest crack the fleet's inspections measured below a_crit (model.extrapolation's
        a_s; 0 for a model fitted before it): where an uninspected tail's drift starts."""
        return 0.0 if self.extrapolation is None else self.extrapolation.seen_crack_m


def default_box(
    stress_range_mpa: Tensor, law: ParisLaw, observations: Observations | None = None
) -> InputBox:
    """Scale stress over the flown range and cracks over [a0, a_crit], the range a forecast
    needs, or where `observations` are given over [a0, the longest measured crack that did not
    run away (ParisLaw.runaway_crack_m), at most a_crit]: a kernel's correction is held at its
    box's edge, so the network corrects the physics only over cracks that inspections have seen,
    and past them the physics (its C and m, model.paris_calibration) carries the trend.  Its
    own extrapolation did not: on Hudak's alloy-A specimens, with measurements up to 30,000
    cycles, the residual hybrid's later cracks came out 4.7 % off (median, max 105 %) against
    the per-specimen Paris fits' 1.6 % (max 9.2 %; benchmarks/RESULTS.md)."""
    flown = stress_range_mpa[stress_range_mpa > 0]
    if flown.numel() == 0:
        raise ValueError("stress_range_mpa holds no flight with a positive stress range")
    lo, hi = float(flown.min()), float(flown.max())
    if hi - lo < 1e-6 * max(hi, 1.0):
        lo, hi = 0.9 * lo, 1.1 * hi  # one load level: keep a non-empty box around it
    top = law.critical_crack_m
    if observations is not None:
        seen = observations.crack_length_m[observations.measured].double()
        seen = seen[(seen > law.initial_crack_m) & (seen < law.runaway_crack_m)]
        if len(seen):
            top = min(float(seen.max()), law.critical_crack_m)
    return InputBox((lo, hi), (law.initial_crack_m, top))


class CrackGrowthModel(nn.Module):
    """Crack length of each aircraft after every flight, from its stress-range history.

    seed: its network's initial weights, drawn from a generator of its own: torch's
    process-wide one is shared by every thread of the process (the worker's cache thread and
    the API's requests load models, each load drawing from it), so a retrain that seeded it
    and then drew got other weights when another thread drew in between (issue 20).
    """

    def __init__(self, spec: ModelSpec, seed: int = 0) -> None:
        super().__init__()
        self.spec = spec
        kernel = KERNELS[spec.kernel].from_spec(spec.hidden, spec.box, spec.law)
        generator = torch.Generator().manual_seed(seed)
        for part in kernel.modules():
            if isinstance(part, MLP):
                part.draw_initial(generator)
        self.cell = DamageCell(kernel, spec.law, spec.growth_law, STEPS[spec.step])
        self.double()
        # functional_call swaps the module's parameters for the given weights while it runs, so
        # two threads marching one model (the service's model cache) must take turns.
        self._swap_lock = threading.Lock()

    @property
    def kernel(self) -> DamageKernel:
        return self.cell.kernel

    def network_parameters(self) -> dict[str, Tensor]:
        """The trainable weights by name, in the order posteriors flatten them (model.flat)."""
        return {name: p for name, p in self.named_parameters() if p.requires_grad}

    def forward(
        self,
        stress_range_mpa: Tensor,
        lengths: Tensor,
        initial_crack_m: Tensor,
        growth_factor: Tensor | None = None,
        method: str = "auto",
        at: tuple[Tensor, Tensor] | None = None,
    ) -> Tensor:
        """Crack length (aircraft, flights + 1) in m; index k is the crack after k flights.  A
        crack that has run past fracture (or whose march turned nan) is held at
        spec.law.held_crack_m (model.physics).  at: (rows, flights), each (points,): only the
        crack at those points (points,), as trajectory[rows, flights]; the compiled march reads
        them without building the trajectory where no gradient is needed
        (fast_march.fast_march_at), and without handing it to torch where one is
        (fast_march.fast_march_points: the same bits and gradients).

        stress_range_mpa: (aircraft, flights) MPa, zero-padded; lengths: (aircraft,) real flights;
        initial_crack_m: (aircraft,) m; growth_factor: (aircraft,) per-tail multiplier of the
        growth rate (default 1).  method: "fast" (compiled march with an adjoint backward,
        model/fast_march.py), "sequential" (the reference loop, autograd through every step) or
        "auto" (fast whenever it supports the whole cell (kernel, growth law, step) and the
        inputs, else sequential).  Every march in fleetpinn goes through here, so
        torch.func.functional_call(model, weights, args) marches any weights.  Raises ValueError
        for an unknown method, or for "fast" where the compiled march cannot run.
        """
        if method not in MARCH_METHODS:
            raise ValueError(f"method must be one of {MARCH_METHODS}, got {method!r}")
        initial_crack_m = initial_crack_m.to(stress_range_mpa.dtype)
        fast = method == "fast" or (
            method == "auto" and unsupported_reason(self.cell, stress_range_mpa) is None
        )
        if fast and at is not None:
            args = (stress_range_mpa, lengths, initial_crack_m, growth_factor)
            if self._needs_grad(initial_crack_m, growth_factor):
                return fast_march_points(self.cell, *args, *at)
            return fast_march_at(self.cell, *args, *at)
        if fast:
            traj = fast_march(self.cell, stress_range_mpa, lengths, initial_crack_m, growth_factor)
        else:
            factor = None if growth_factor is None else growth_factor.to(stress_range_mpa.dtype)
            mask = LoadHistory(stress_range_mpa, lengths).mask
            traj = march(
                lambda a, s: self.cell(a, s, factor), stress_range_mpa, initial_crack_m, mask
            )
        return traj if at is None else traj[at]

    def _needs_grad(self, *inputs: Tensor | None) -> bool:
        """Whether a march of these inputs under the current weights records a gradient."""
        leaves = [*self.parameters(), *(x for x in inputs if x is not None)]
        return torch.is_grad_enabled() and any(x.requires_grad for x in leaves)

    def trajectory_with(
        self,
        flat_weights: Tensor,
        stress_range_mpa: Tensor,
        lengths: Tensor,
        initial_crack_m: Tensor,
        growth_factor: Tensor | None = None,
        at: tuple[Tensor, Tensor] | None = None,
    ) -> Tensor:
        """`forward` under other weights (`at` as there): flat_weights (parameters,) in
        `network_parameters` order (model.flat), e.g. a posterior draw; the model's own weights
        are untouched.
        Concurrent calls on one model take turns; any other use of the model from another
        thread while one runs would see the swapped weights (the service gives each thread its
        own model, app.services.models)."""
        with self._swap_lock:
            like = self.network_parameters()
            weights = dict(zip(like, unflatten(flat_weights, list(like.values())), strict=True))
            out: Tensor = functional_call(
                self,
                weights,
                (stress_range_mpa, lengths, initial_crack_m, growth_factor),
                {"at": at},
            )
        return out

    def loads_for(self, loads: LoadHistory) -> LoadHistory:
        """`loads` with its march input reduced under this model's law (model.growth_laws): the
        history itself where its flights were recorded as one range each.  Whatever marches a
        history's stress_range_mpa through `forward` takes it from here."""
        return loads.for_law(self.spec.growth_law, self.spec.law.constants)

    def trajectory(
        self, loads: LoadHistory, initial_crack_m: Tensor | None = None, *, method: str = "auto"
    ) -> Tensor:
        """`forward` on a LoadHistory (reduced under this model's law, `loads_for`): its own
        initial cracks (else the law's a0) unless initial_crack_m (aircraft,) is given, and its
        growth factors."""
        loads = self.loads_for(loads)
        if initial_crack_m is None:
            initial_crack_m = loads.initial_or(self.spec.law.initial_crack_m)
        return self(
            loads.stress_range_mpa, loads.lengths, initial_crack_m, loads.growth_factor, method
        )

    def final_crack(self, loads: LoadHistory) -> Tensor:
        """Crack length (aircraft,) after each aircraft's last recorded flight."""
        traj = self.trajectory(loads)
        return traj[torch.arange(traj.shape[0]), loads.lengths]

    def at(self, loads: LoadHistory, observations: Observations) -> Tensor:
        """Predicted crack length at each observation."""
        return at_flights(self.trajectory(loads), observations)
