"""Validated flight and inspection records as model inputs: a LoadHistory and Observations."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
import torch
from torch import Tensor

from model.integrate import LoadHistory, Observations
from model.records import RecordError


@dataclass(frozen=True)
class TrainingData:
    """Validated records as model inputs.

    tails: aircraft index -> tail (sorted).  loads: stress ranges (aircraft, flights) float64,
    each tail's flights in flown_at order.  observations: one per inspection, `flights` = number
    of the tail's flights flown strictly before inspected_at.  flights: the ordered flights table
    (tail, flight_id, flown_at, stress_range_mpa, mission) plus `aircraft` (index into tails) and
    `flight` (1-based position: the crack after it is trajectory[aircraft, flight]).
    """

    tails: list[str]
    loads: LoadHistory
    observations: Observations
    flights: pd.DataFrame


def _time_ns(series: pd.Series) -> np.ndarray:
    return (
        series.dt.tz_convert("UTC").dt.tz_localize(None).dt.as_unit("ns").to_numpy().view("int64")
    )


def _censoring(inspections: pd.DataFrame) -> tuple[Tensor | None, Tensor | None, Tensor | None]:
    """Observations' (detected, detection_a50_m, detection_a90_m) from validated inspections:
    None, None, None when every row is a measurement; a hard threshold is a50 = a90."""
    if "detected" not in inspections.columns or bool(inspections["detected"].all()):
        return None, None, None
    threshold = inspections["detection_threshold_m"].to_numpy(dtype=np.float64)
    hard = ~np.isnan(threshold)
    a50 = np.where(hard, threshold, inspections["pod_a50_m"].to_numpy(dtype=np.float64))
    a90 = np.where(hard, threshold, inspections["pod_a90_m"].to_numpy(dtype=np.float64))
    detected = inspections["detected"].to_numpy(dtype=bool)
    # measured rows carry no curve: any positive placeholder (read only where not detected)
    a50, a90 = np.where(detected, 1.0, a50), np.where(detected, 1.0, a90)
    return (
        torch.from_numpy(detected.copy()),
        torch.from_numpy(a50.copy()),
        torch.from_numpy(a90.copy()),
    )


def assemble(
    flights: pd.DataFrame, inspections: pd.DataFrame | None = None, source: str = "inspections"
) -> TrainingData:
    """Map validated flights and inspections (from validate_*) to a LoadHistory and Observations.

    Vectorised: flights are ordered by a lexsort on (tail, flown_at, flight_id); each
    inspection's flight count comes from one merged sort of flight and inspection times, an
    inspection sorting before a flight at the same instant (strictly before).  Raises RecordError
    (named `source`, column tail) for an inspection of a tail with no flights.
    """
    tail_code, tails = pd.factorize(flights["tail"], sort=True)
    flown_ns = _time_ns(flights["flown_at"])
    order = np.lexsort((flown_ns, tail_code))
    tied = (np.diff(tail_code[order]) == 0) & (np.diff(flown_ns[order]) == 0)
    if tied.any():  # rare: sort by id as well (hashing every id is the slow part)
        id_code = pd.factorize(flights["flight_id"], sort=True)[0]
        order = np.lexsort((id_code, flown_ns, tail_code))
    tail_sorted = tail_code[order].astype(np.int64)
    counts = np.bincount(tail_sorted, minlength=len(tails))
    starts = np.concatenate(([0], np.cumsum(counts)[:-1])).astype(np.int64)
    position = np.arange(len(order), dtype=np.int64) - starts[tail_sorted]
    stress = np.zeros((len(tails), int(counts.max()) if len(tails) else 0), dtype=np.float64)
    stress[tail_sorted, position] = flights["stress_range_mpa"].to_numpy(dtype=np.float64)[order]
    loads = LoadHistory(torch.from_numpy(stress), torch.from_numpy(counts.astype(np.int64)))

    ordered = flights.iloc[order].copy()
    ordered["aircraft"] = tail_sorted
    ordered["flight"] = position + 1

    if inspections is None or inspections.empty:
        empty = torch.zeros(0, dtype=torch.long)
        observations = Observations(empty, empty.clone(), torch.zeros(0, dtype=torch.float64))
        return TrainingData(list(map(str, tails)), loads, observations, ordered)

    aircraft = pd.Index(tails).get_indexer(inspections["tail"])
    if (aircraft < 0).any():
        i = int(np.argmax(aircraft < 0))
        tail = inspections["tail"].iloc[i]
        raise RecordError(
            source, int(inspections.index[i]), "tail", f"unknown tail {tail!r} (no flights)"
        )
    # One merged sort per (tail, time, kind): kind 0 (inspection) before 1 (flight) at a tie.
    n_flights, n_insp = len(order), len(aircraft)
    event_tail = np.concatenate((tail_sorted, aircraft.astype(np.int64)))
    event_time = np.concatenate((flown_ns[order], _time_ns(inspections["inspected_at"])))
    event_kind = np.concatenate((np.ones(n_flights, np.int8), np.zeros(n_insp, np.int8)))
    merged = np.lexsort((event_kind, event_time, event_tail))
    flights_so_far = np.cumsum(event_kind[merged].astype(np.int64))
    is_insp = merged >= n_flights
    before = np.empty(n_insp, dtype=np.int64)
    insp_tail = event_tail[merged[is_insp]]
    # cumsum counts flights of earlier tails too; subtract the flights of tails sorted before.
    before[merged[is_insp] - n_flights] = flights_so_far[is_insp] - starts[insp_tail]
    observations = Observations(
        torch.from_numpy(aircraft.astype(np.int64)),
        torch.from_numpy(before),
        torch.from_numpy(inspections["crack_length_m"].to_numpy(dtype=np.float64).copy()),
        *_censoring(inspections),
    )
    return TrainingData(list(map(str, tails)), loads, observations, ordered)
