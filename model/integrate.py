"""The time march: roll a cell over a (ragged) batch of input sequences.

`march` is the plain sequential loop, the reference every faster path is tested against.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import torch
from torch import Tensor

from model.growth_laws import GROWTH_LAWS, CycleSpectrum, GrowthConstants

# z such that Phi(z) = 0.9: a log-normal PoD reaches 90 % at a50 * exp(Z90 * s)
Z90 = 1.2815515655446004


def detection_scale(a50_m: Tensor, a90_m: Tensor | None, sizing_sd: float | Tensor) -> Tensor:
    """The sd in ln a of a no-find's probit, P(not detected | a) = Phi((ln a50 - ln a) / scale):
    the PoD curve's s = ln(a90 / a50) / Z90 (0 for a hard threshold: a90 None or a50) seen
    through the log-normal sizing error, scale = sqrt(s**2 + sizing_sd**2), elementwise."""
    spread = torch.zeros_like(a50_m) if a90_m is None else torch.log(a90_m / a50_m) / Z90
    return torch.sqrt(spread**2 + sizing_sd**2)


@dataclass(frozen=True)
class LoadHistory:
    """The loads of a batch of aircraft as named per-flight channels, zero-padded to the longest
    history.

    stress_range_mpa: (aircraft, flights) the one range per flight every march steps with: the
    recorded range where a flight was recorded as one, else the damage-equivalent range of its
    cycles under the law named in `reduced_for` (model.growth_laws; `for_law` recomputes it for
    another law's exponents).  cycles: each flight's cycles (range, load ratio, count), where
    they were recorded, kept so that a law can be refitted to them.
    lengths: (aircraft,) number of real flights of each;
    initial_crack_m: (aircraft,) crack before the first flight in m, or None for the model's a0
    (a history restarted by a repair starts from the crack left by the repair).
    growth_factor: (aircraft,) multiplier of each aircraft's growth rate (its own scatter about
    the fleet's, model.tracking), or None for 1.
    reduced_for: (law name, m, gamma[, its cycle weight's terms]) that stress_range_mpa was
    reduced under; None where it was recorded (no cycles).
    """

    stress_range_mpa: Tensor
    lengths: Tensor
    initial_crack_m: Tensor | None = None
    growth_factor: Tensor | None = None
    cycles: CycleSpectrum | None = None
    reduced_for: tuple[str | float, ...] | None = None

    def __post_init__(self) -> None:
        if self.stress_range_mpa.dim() != 2:
            raise ValueError("stress_range_mpa must be (aircraft, flights)")
        if self.lengths.shape != self.stress_range_mpa.shape[:1]:
            raise ValueError("lengths must have one entry per aircraft")
        if len(self.lengths) and (
            int(self.lengths.min()) < 0 or int(self.lengths.max()) > self.stress_range_mpa.shape[1]
        ):
            raise ValueError("lengths must lie in [0, flights]")
        for name in ("initial_crack_m", "growth_factor"):
            values = getattr(self, name)
            if values is not None and values.shape != self.lengths.shape:
                raise ValueError(f"{name} must have one entry per aircraft")
        if self.cycles is not None:
            if self.cycles.stress_range_mpa.shape[:2] != self.stress_range_mpa.shape:
                raise ValueError("cycles must be (aircraft, flights, cycles) of the same flights")
            if self.reduced_for is None:
                raise ValueError("a history with cycles must say which law reduced them")

    @classmethod
    def from_cycles(
        cls,
        cycles: CycleSpectrum,
        lengths: Tensor,
        growth_law: str,
        constants: GrowthConstants,
        dtype: torch.dtype = torch.float64,
    ) -> LoadHistory:
        """A history recorded as cycles, its march input reduced under the law (model.growth_laws)."""
        law = GROWTH_LAWS[growth_law]
        stress = law.equivalent_range(cycles, constants).to(dtype)
        return cls(stress, lengths, cycles=cycles, reduced_for=_law_key(growth_law, constants))

    @property
    def channels(self) -> dict[str, Tensor]:
        """The named channels: stress_range_mpa (aircraft, flights) and, where cycles were
        recorded, cycle_range_mpa, cycle_load_ratio and cycle_count (aircraft, flights, cycles)."""
        named = {"stress_range_mpa": self.stress_range_mpa}
        if self.cycles is not None:
            named["cycle_range_mpa"] = self.cycles.stress_range_mpa
            named["cycle_load_ratio"] = self.cycles.load_ratio
            named["cycle_count"] = self.cycles.count
        return named

    def for_law(self, growth_law: str, constants: GrowthConstants) -> LoadHistory:
        """This history with its march input reduced under another law's exponents; itself
        where the flights were recorded as one range each, or reduced alike already."""
        key = _law_key(growth_law, constants)
        if self.cycles is None or key == self.reduced_for:
            return self
        stress = GROWTH_LAWS[growth_law].equivalent_range(self.cycles, constants)
        return replace(
            self, stress_range_mpa=stress.to(self.stress_range_mpa.dtype), reduced_for=key
        )

    @classmethod
    def from_sequences(
        cls, sequences: Sequence[Sequence[float] | Tensor], dtype: torch.dtype = torch.float64
    ) -> LoadHistory:
        """Pad a list of per-aircraft stress-range sequences (MPa) into one batch."""
        lengths = torch.tensor([len(s) for s in sequences], dtype=torch.long)
        steps = int(lengths.max()) if len(sequences) else 0
        padded = torch.zeros(len(sequences), steps, dtype=dtype)
        for i, seq in enumerate(sequences):
            padded[i, : len(seq)] = torch.as_tensor(seq, dtype=dtype)
        return cls(padded, lengths)

    @property
    def mask(self) -> Tensor:  # (aircraft, flights) True where a flight was flown
        steps = torch.arange(self.stress_range_mpa.shape[1], device=self.lengths.device)
        return steps.unsqueeze(0) < self.lengths.unsqueeze(1)

    def to(self, dtype: torch.dtype) -> LoadHistory:
        return replace(self, stress_range_mpa=self.stress_range_mpa.to(dtype))

    def select(self, aircraft: Tensor) -> LoadHistory:
        """The sub-batch of the given aircraft indices, trimmed to its longest history."""
        lengths = self.lengths[aircraft]
        steps = int(lengths.max()) if len(lengths) else 0

        def pick(values: Tensor | None) -> Tensor | None:
            return None if values is None else values[aircraft]

        return LoadHistory(
            self.stress_range_mpa[aircraft, :steps],
            lengths,
            pick(self.initial_crack_m),
            pick(self.growth_factor),
            None if self.cycles is None else self.cycles.pick(aircraft, steps),
            self.reduced_for,
        )

    def until(self, flights: int) -> LoadHistory:
        """Each history cut after its first `flights` flights: all a march needs that reports
        nothing later (its cost grows with the flights it marches)."""
        return replace(
            self,
            stress_range_mpa=self.stress_range_mpa[:, :flights],
            lengths=self.lengths.clamp_max(flights),
            cycles=None if self.cycles is None else self.cycles.pick(slice(None), flights),
        )

    def initial_or(self, default_m: float) -> Tensor:
        """(aircraft,) initial cracks in m, `default_m` where the history sets none, float64."""
        if self.initial_crack_m is not None:
            return self.initial_crack_m.to(torch.float64)
        return torch.full(self.lengths.shape, default_m, dtype=torch.float64)


def _law_key(growth_law: str, constants: GrowthConstants) -> tuple[str | float, ...]:
    """What a reduction to one range per flight depends on: the law's m and gamma (C scales
    the rate, not the range), and the terms of its cycle weight where it has one (NASGRO's
    closure)."""
    law = GROWTH_LAWS[growth_law]
    gamma = law.gamma(constants)
    return (growth_law, float(constants.m), float(gamma), *law.weight_terms(constants))


@dataclass(frozen=True)
class Observations:
    """Crack lengths observed after `flights` flights of aircraft `aircraft` (index in the batch).

    flights = 0 observes the initial crack.  All tensors are (observations,).

    Censoring (optional): `detected` False marks an inspection that found no crack.  Its
    crack_length_m is not a measurement (any value, NaN included, is ignored); what it says is
    that the crack was probably below the method's detection threshold, described by a
    log-normal probability-of-detection curve PoD(a) = Phi((ln a - ln a50) / s),
    s = (ln a90 - ln a50) / z_0.9: `detection_a50_m` is a50 (for a hard threshold, the
    threshold) and `detection_a90_m` is a90 (None, or equal to a50, for a hard threshold).
    Both are read only where detected is False.  Without `detected` every row is a measurement.
    """

    aircraft: Tensor
    flights: Tensor
    crack_length_m: Tensor
    detected: Tensor | None = None
    detection_a50_m: Tensor | None = None
    detection_a90_m: Tensor | None = None

    def __post_init__(self) -> None:
        n = self.aircraft.shape
        if self.flights.shape != n or self.crack_length_m.shape != n:
            raise ValueError("aircraft, flights and crack_length_m must have the same length")
        if self.detected is None:
            if self.detection_a50_m is not None or self.detection_a90_m is not None:
                raise ValueError("detection_a50_m / detection_a90_m need `detected`")
            return
        if self.detected.shape != n or self.detected.dtype != torch.bool:
            raise ValueError("detected must be a bool tensor with one entry per observation")
        missed = ~self.detected
        if self.detection_a50_m is None or self.detection_a50_m.shape != n:
            raise ValueError("detection_a50_m must give one threshold per observation")
        a50 = self.detection_a50_m[missed]
        if not bool((a50 > 0).all()):
            raise ValueError("detection_a50_m must be > 0 where detected is False")
        if self.detection_a90_m is not None:
            if self.detection_a90_m.shape != n:
                raise ValueError("detection_a90_m must have one entry per observation")
            if not bool((self.detection_a90_m[missed] >= a50).all()):
                raise ValueError("detection_a90_m must be >= detection_a50_m")
        measured = self.crack_length_m[self.detected]
        if not bool((measured > 0).all()):
            raise ValueError("crack_length_m must be > 0 where detected is True")

    @property
    def measured(self) -> Tensor:
        """(observations,) bool: True where the row measured a crack (not a non-detection)."""
        if self.detected is None:
            return torch.ones(self.aircraft.shape, dtype=torch.bool)
        return self.detected

    @property
    def censored(self) -> bool:
        """Whether any observation is a non-detection."""
        return self.detected is not None and not bool(self.detected.all())

    def subset(self, rows: Tensor, aircraft: Tensor | None = None) -> Observations:
        """The observations at `rows` (index or bool mask), optionally re-indexed to `aircraft`."""

        def pick(values: Tensor | None) -> Tensor | None:
            return None if values is None else values[rows]

        return Observations(
            self.aircraft[rows] if aircraft is None else aircraft,
            self.flights[rows],
            self.crack_length_m[rows],
            pick(self.detected),
            pick(self.detection_a50_m),
            pick(self.detection_a90_m),
        )


def march(
    cell: Callable[[Tensor, Tensor], Tensor],
    inputs: Tensor,
    initial: Tensor,
    mask: Tensor | None = None,
) -> Tensor:
    """Sequential reference march: state_k = cell(state_{k-1}, inputs[:, k-1]) where mask allows.

    inputs: (batch, steps, ...) ; initial: (batch, *state) ; mask: (batch, steps) bool, False
    steps keep the previous state (ragged batches).  Returns (batch, steps + 1, *state) with the
    initial state at index 0.
    """
    states = [initial]
    state = initial
    for k in range(inputs.shape[1]):
        stepped = cell(state, inputs[:, k])
        if mask is not None:
            keep = mask[:, k].reshape(-1, *([1] * (state.dim() - 1)))
            stepped = torch.where(keep, stepped, state)
        state = stepped
        states.append(state)
    return torch.stack(states, dim=1)


def at_flights(trajectory: Tensor, observations: Observations) -> Tensor:
    """Pick trajectory values (aircraft, flights + 1) at the observed (aircraft, flights) pairs."""
    return trajectory[observations.aircraft, observations.flights]
