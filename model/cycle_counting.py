"""A flight's load record as cycles: (range, load ratio, count) from what an airline records.

Three forms (docs/api.md): cycles with range and load ratio R = S_min / S_max, cycles with their
maximum and minimum stress, or a stress history (peaks and valleys, or a sampled series) that is
counted into cycles by rainflow (the `rainflow` package: ASTM E1049-85's four-point method,
residual half cycles counted 0.5 as the standard says; a sampled series is reduced to its
reversals first).  A cycle whose maximum stress is not above zero never opens the crack and is
dropped; R must stay below 1.  Errors say which field and value: the caller names the flight.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import rainflow
import torch

from model.growth_laws import GROWTH_LAWS, CycleSpectrum, GrowthConstants

# a flight's history holds at most this many points, its cycles at most this many rows
MAX_HISTORY_POINTS = 100_000
MAX_CYCLES = 10_000


class CycleError(ValueError):
    """A bad cycle or history: `field` names the field, str() says what is wrong."""

    def __init__(self, field: str, reason: str) -> None:
        self.field = field
        super().__init__(reason)


@dataclass(frozen=True)
class FlightCycles:
    """One flight's cycles: stress_range_mpa, load_ratio, count (each (cycles,))."""

    stress_range_mpa: np.ndarray
    load_ratio: np.ndarray
    count: np.ndarray

    def __len__(self) -> int:
        return len(self.count)

    def packed(self) -> bytes:
        """(cycles, 3) float64 little-endian: range, R, count (how the service stores them)."""
        table = np.stack([self.stress_range_mpa, self.load_ratio, self.count], axis=1)
        return table.astype("<f8").tobytes()

    @classmethod
    def unpacked(cls, data: bytes) -> FlightCycles:
        table = np.frombuffer(data, dtype="<f8").reshape(-1, 3)
        return cls(table[:, 0].copy(), table[:, 1].copy(), table[:, 2].copy())

    def equivalent_range(self, growth_law: str, constants: GrowthConstants) -> float:
        """The flight's damage-equivalent range under the law (model.growth_laws), MPa."""
        spectrum = CycleSpectrum(
            *(torch.from_numpy(np.asarray(v, dtype=np.float64))[None, None] for v in self.columns)
        )
        return float(GROWTH_LAWS[growth_law].equivalent_range(spectrum, constants)[0, 0])

    @property
    def columns(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.stress_range_mpa, self.load_ratio, self.count


def _numbers(values: Sequence[object], field: str) -> np.ndarray:
    """Finite floats from JSON values; CycleError naming the first bad one."""
    out = np.empty(len(values))
    for i, value in enumerate(values):
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise CycleError(field, f"value {i} must be a number, got {value!r}")
        if not math.isfinite(value):
            raise CycleError(field, f"value {i} must be finite, got {value!r}")
        out[i] = float(value)
    return out


def from_history(history: Sequence[object], field: str = "stress_history_mpa") -> FlightCycles:
    """Rainflow cycles of a stress history in MPa (peaks and valleys, or a sampled series)."""
    values = _numbers(history, field)
    if len(values) < 2:
        raise CycleError(field, f"needs at least 2 points, got {len(values)}")
    if len(values) > MAX_HISTORY_POINTS:
        raise CycleError(field, f"at most {MAX_HISTORY_POINTS} points, got {len(values)}")
    ranges, ratios, counts = [], [], []
    for rng, _, count, start, end in _rainflow(values):
        # the cycle's own points, not mean +- range / 2, which lost a tiny tensile peak (5e-324)
        high, low = max(values[start], values[end]), min(values[start], values[end])
        if rng > 0 and high > 0:
            ranges.append(rng)
            ratios.append(low / high)
            counts.append(count)
    if not ranges:
        raise CycleError(field, "holds no cycle with a tensile maximum stress (> 0 MPa)")
    return FlightCycles(np.array(ranges), np.array(ratios), np.array(counts))


def _rainflow(values: np.ndarray) -> list[tuple[float, float, float, int, int]]:
    """rainflow.extract_cycles' (range, mean, count, start, end), with two points' half cycle,
    which it leaves out (it counts [5, 0] as no cycle; ASTM E1049's residue is a half cycle)."""
    if len(values) == 2:
        first, last = float(values[0]), float(values[1])
        return [(abs(last - first), (first + last) / 2, 0.5, 0, 1)] if first != last else []
    return list(rainflow.extract_cycles(values))


def from_cycles(cycles: Sequence[dict[str, object]], field: str = "cycles") -> FlightCycles:
    """Cycles given as {stress_range_mpa, load_ratio} or {max_stress_mpa, min_stress_mpa}, each
    with an optional count (default 1; 0.5 a half cycle)."""
    if not cycles:
        raise CycleError(field, "needs at least 1 cycle")
    if len(cycles) > MAX_CYCLES:
        raise CycleError(field, f"at most {MAX_CYCLES} cycles, got {len(cycles)}")
    ranges, ratios, counts = np.empty(len(cycles)), np.empty(len(cycles)), np.empty(len(cycles))
    for i, cycle in enumerate(cycles):
        where = f"{field}[{i}]"
        given = {k for k, v in cycle.items() if v is not None}
        count = _numbers([cycle.get("count", 1.0)], f"{where}.count")[0]
        if not count > 0:
            raise CycleError(f"{where}.count", f"must be > 0, got {count}")
        if given >= {"stress_range_mpa", "load_ratio"} and not given & {
            "max_stress_mpa",
            "min_stress_mpa",
        }:
            rng = _numbers([cycle["stress_range_mpa"]], f"{where}.stress_range_mpa")[0]
            ratio = _numbers([cycle["load_ratio"]], f"{where}.load_ratio")[0]
            if not rng > 0:
                raise CycleError(f"{where}.stress_range_mpa", f"must be > 0, got {rng}")
            if not ratio < 1:
                raise CycleError(f"{where}.load_ratio", f"must be < 1, got {ratio}")
        elif given >= {"max_stress_mpa", "min_stress_mpa"} and not given & {
            "stress_range_mpa",
            "load_ratio",
        }:
            high = _numbers([cycle["max_stress_mpa"]], f"{where}.max_stress_mpa")[0]
            low = _numbers([cycle["min_stress_mpa"]], f"{where}.min_stress_mpa")[0]
            if not high > 0:
                raise CycleError(f"{where}.max_stress_mpa", f"must be > 0, got {high}")
            if not low < high:
                raise CycleError(
                    f"{where}.min_stress_mpa", f"must be below max_stress_mpa {high}, got {low}"
                )
            rng, ratio = high - low, low / high
        else:
            raise CycleError(
                where,
                "give stress_range_mpa and load_ratio, or max_stress_mpa and min_stress_mpa",
            )
        ranges[i], ratios[i], counts[i] = rng, ratio, count
    return FlightCycles(ranges, ratios, counts)


def spectrum_of(flights: Sequence[FlightCycles]) -> CycleSpectrum:
    """(1, flights, most cycles) zero-padded channels of one tail's flights in order."""
    width = max((len(f) for f in flights), default=0)
    channels = np.zeros((3, 1, len(flights), max(width, 1)))
    for t, flight in enumerate(flights):
        for c, values in enumerate(flight.columns):
            channels[c, 0, t, : len(flight)] = values
    return CycleSpectrum(*(torch.from_numpy(channels[c]) for c in range(3)))
