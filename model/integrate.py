"""The time march: roll a cell over a (ragged) batch of input sequences.

`march` is the plain sequential loop, the reference every faster path is tested against.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import torch
from torch import Tensor


@dataclass(frozen=True)
class LoadHistory:
    """Per-flight stress ranges of a batch of aircraft, zero-padded to the longest history.

    stress_range_mpa: (aircraft, flights); lengths: (aircraft,) number of real flights of each.
    """

    stress_range_mpa: Tensor
    lengths: Tensor

    def __post_init__(self) -> None:
        if self.stress_range_mpa.dim() != 2:
            raise ValueError("stress_range_mpa must be (aircraft, flights)")
        if self.lengths.shape != self.stress_range_mpa.shape[:1]:
            raise ValueError("lengths must have one entry per aircraft")
        if len(self.lengths) and (
            int(self.lengths.min()) < 0 or int(self.lengths.max()) > self.stress_range_mpa.shape[1]
        ):
            raise ValueError("lengths must lie in [0, flights]")

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
        return LoadHistory(self.stress_range_mpa.to(dtype), self.lengths)

    def select(self, aircraft: Tensor) -> LoadHistory:
        """The sub-batch of the given aircraft indices, trimmed to its longest history."""
        lengths = self.lengths[aircraft]
        steps = int(lengths.max()) if len(lengths) else 0
        return LoadHistory(self.stress_range_mpa[aircraft, :steps], lengths)


@dataclass(frozen=True)
class Observations:
    """Crack lengths observed after `flights` flights of aircraft `aircraft` (index in the batch).

    flights = 0 observes the initial crack.  All tensors are (observations,).
    """

    aircraft: Tensor
    flights: Tensor
    crack_length_m: Tensor

    def __post_init__(self) -> None:
        n = self.aircraft.shape
        if self.flights.shape != n or self.crack_length_m.shape != n:
            raise ValueError("aircraft, flights and crack_length_m must have the same length")


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
