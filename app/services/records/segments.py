"""A tail's history split at its repairs: each segment restarts the crack at its own value.

An inspection with `repaired` true restarts its tail's crack at crack_after_repair_m after every
flight flown before it.  Segment 0 of a tail starts at the tail's initial crack (or the model's
a0); segment j >= 1 starts at repair j's crack_after_repair_m and holds the flights flown from
that inspection on.  An inspection belongs to the segment in force when it was made; the
repairing inspection itself observes the crack before its repair (the end of the previous
segment).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
import torch
from torch import Tensor

from model.growth_laws import CycleSpectrum
from model.integrate import LoadHistory, Observations
from model.training_data import TrainingData


@dataclass(frozen=True)
class Segments:
    """Segments of a batch of tails, in tail order, each tail's segments in time order.

    loads: (segments, flights) stress ranges of each segment (with their cycles, where the
    history carries them), with the crack it starts from;
    tail: (segments,) index into the tails; start: (segments,) flights of the tail flown before
    the segment; last: (tails,) index of each tail's last (current) segment; observations: the
    inspections located on the segments (aircraft = segment index, flights counted from the
    segment's start).
    """

    loads: LoadHistory
    tail: np.ndarray
    start: np.ndarray
    last: np.ndarray
    observations: Observations


def _ns(times: pd.Series) -> np.ndarray:
    return times.dt.tz_convert("UTC").dt.tz_localize(None).dt.as_unit("ns").to_numpy().view("int64")


def _segment_rows(values: Tensor, pieces: list[tuple[int, int, int]], steps: int) -> Tensor:
    """(segments, steps, ...) each segment's flights of `values` (tails, flights, ...), from
    pieces of (tail, first flight, flights)."""
    padded = torch.zeros(len(pieces), steps, *values.shape[2:], dtype=values.dtype)
    for s, (t, a, n) in enumerate(pieces):
        padded[s, :n] = values[t, a : a + n]
    return padded


def split_at_repairs(
    data: TrainingData, inspections: pd.DataFrame | None, initial_crack_m: Tensor
) -> Segments:
    """Segments of data's tails (see the module docstring).

    inspections: the frame data.observations were assembled from (same row order), with a
    `repaired` and `crack_after_repair_m` column (None or without them: no repair);
    initial_crack_m: (tails,) the crack each tail's first segment starts from.
    """
    tails = len(data.tails)
    obs = data.observations
    lengths = data.loads.lengths.numpy()
    has_repairs = inspections is not None and "repaired" in inspections.columns
    times = (
        _ns(inspections["inspected_at"]) if inspections is not None and len(obs.aircraft) else None
    )
    repairs: dict[int, list[tuple[int, int, float]]] = {}
    if has_repairs and times is not None:
        assert inspections is not None
        after = inspections["crack_after_repair_m"].to_numpy(dtype=np.float64)
        for row in np.flatnonzero(inspections["repaired"].to_numpy(dtype=bool)):
            tail = int(obs.aircraft[row])
            repairs.setdefault(tail, []).append(
                (int(times[row]), int(obs.flights[row]), after[row])
            )
    seg_tail: list[int] = []
    seg_start: list[int] = []
    seg_end: list[int] = []
    seg_initial: list[float] = []
    first = np.zeros(tails, dtype=np.int64)
    repair_times: list[np.ndarray] = []
    for t in range(tails):
        events = sorted(repairs.get(t, []))
        first[t] = len(seg_tail)
        starts = [0] + [flights for _, flights, _ in events]
        seg_start += starts
        seg_end += [*starts[1:], int(lengths[t])]
        seg_initial += [float(initial_crack_m[t]), *(crack for _, _, crack in events)]
        seg_tail += [t] * len(starts)
        repair_times.append(np.array([time for time, _, _ in events], dtype=np.int64))
    start = np.array(seg_start, dtype=np.int64)
    size = np.array(seg_end, dtype=np.int64) - start
    steps = int(size.max()) if len(size) else 0
    pieces = list(zip(seg_tail, start, size, strict=True))
    padded = _segment_rows(data.loads.stress_range_mpa, pieces, steps)
    cycles = data.loads.cycles
    if cycles is not None:  # each segment's flights keep their cycles
        cycles = CycleSpectrum(
            *(
                _segment_rows(c, pieces, steps)
                for c in (cycles.stress_range_mpa, cycles.load_ratio, cycles.count)
            )
        )
    segment = obs.aircraft.numpy().copy()
    if times is not None:
        for i, t in enumerate(obs.aircraft.tolist()):
            segment[i] = first[t] + int((repair_times[t] < times[i]).sum())
    observations = obs.subset(
        torch.arange(len(segment)), torch.from_numpy(segment.astype(np.int64))
    )
    observations = Observations(
        observations.aircraft,
        observations.flights - torch.from_numpy(start[segment]),
        observations.crack_length_m,
        observations.detected,
        observations.detection_a50_m,
        observations.detection_a90_m,
    )
    last = np.append(first[1:], len(seg_tail)) - 1
    return Segments(
        LoadHistory(
            padded,
            torch.from_numpy(size),
            torch.tensor(seg_initial, dtype=torch.float64),
            cycles=cycles,
            reduced_for=data.loads.reduced_for,
        ),
        np.array(seg_tail, dtype=np.int64),
        start,
        last,
        observations,
    )
