"""Flights sent as cycles or as a stress history: counted, reduced to one range, stored as sent.

A flight's loads come in one of three forms (app.schemas.FlightIn): one stress range, its
cycles, or a stress history counted into cycles by rainflow (model.cycle_counting).  The
flight's stress_range_mpa becomes its cycles' damage-equivalent range under the configured law
(settings growth_law and its constants, model.growth_laws), so every forecast and retrain reads
flights as before, and the cycles (with the history, where one was sent) are stored in
flight_spectra in the ingest's own transaction, for a later law to be refitted to them.  Any bad
flight refuses the whole request (422 naming the flight and the field) before anything is
written.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import pandas as pd
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.config import Settings
from app.storage import bulk
from app.tables import Flight, FlightSpectrum
from model.cycle_counting import CycleError, FlightCycles, from_cycles, from_history
from model.records import RecordError
from model.spectrum_files import CycleTable, cycle_table

LOAD_FORMS = ("stress_range_mpa", "cycles", "stress_history_mpa")


class Recorded(NamedTuple):
    """What a stored flight recorded besides one range: its cycles and the history they came
    from."""

    recorded: str  # "cycles" or "stress_history"
    cycles: FlightCycles
    stress_history_mpa: np.ndarray | None = None


@dataclass(frozen=True)
class RecordedLoads:
    """What the flights of one ingest recorded besides one range, column-wise: flight f is row f
    of the flights frame handed to the ingest (whose validated rows are indexed by their 1-based
    source row, model.record_validation), with its tail and flight_id; recorded[f] is "cycles",
    "stress_history" or None (one range, no cycles in `cycles`); histories: the histories sent,
    by flight.  One object, not one per flight: a cycle file holds hundreds of thousands."""

    tail: np.ndarray  # (flights,) object
    flight_id: np.ndarray  # (flights,) object
    recorded: np.ndarray  # (flights,) object
    cycles: CycleTable
    histories: dict[int, np.ndarray]


def with_ranges(
    tail: str, flights: Sequence[dict[str, Any]], settings: Settings, source: str = "body"
) -> tuple[list[dict[str, Any]], RecordedLoads | None]:
    """Each flight of `tail` with its one stress_range_mpa (as sent, or its cycles'
    damage-equivalent range), and what the flights sent as cycles or histories recorded (None
    where every flight sent one range).  Raises RecordError (row: the flight's 1-based
    position) naming the flight and the field."""
    law = settings.law()
    out: list[dict[str, Any]] = []
    kinds: list[str | None] = []
    counted: list[FlightCycles] = []
    histories: dict[int, np.ndarray] = {}
    for row, flight in enumerate(flights, start=1):
        name = flight.get("flight_id")
        given = [form for form in LOAD_FORMS if flight.get(form) is not None]
        if len(given) != 1:
            raise RecordError(
                source,
                row,
                given[-1] if given else "stress_range_mpa",
                f"flight {name!r}: give exactly one of {', '.join(LOAD_FORMS)}, "
                f"got {', '.join(given) or 'none'}",
            )
        if given[0] == "stress_range_mpa":
            out.append(flight)
            kinds.append(None)
            counted.append(_NO_CYCLES)
            continue
        try:
            if given[0] == "cycles":
                cycles = from_cycles(flight["cycles"])
                kinds.append("cycles")
            else:
                cycles = from_history(flight["stress_history_mpa"])
                histories[row - 1] = np.asarray(flight["stress_history_mpa"], dtype=np.float64)
                kinds.append("stress_history")
        except CycleError as exc:
            raise RecordError(source, row, exc.field, f"flight {name!r}: {exc}") from exc
        equivalent = cycles.equivalent_range(settings.growth_law, law.constants)
        out.append({**flight, "stress_range_mpa": equivalent})
        counted.append(cycles)
    if not any(kinds):
        return out, None
    sizes = np.array([len(c) for c in counted], dtype=np.int64)
    table = np.concatenate([np.stack(c.columns, axis=1) for c in counted]).reshape(-1, 3)
    return out, RecordedLoads(
        np.array([tail] * len(out), dtype=object),
        np.array([str(f.get("flight_id")) for f in out], dtype=object),
        np.array(kinds, dtype=object),
        CycleTable(np.ascontiguousarray(table), np.concatenate(([0], np.cumsum(sizes)))),
        histories,
    )


_NO_CYCLES = FlightCycles(np.zeros(0), np.zeros(0), np.zeros(0))


def from_cycle_file(
    frame: pd.DataFrame, source: str, settings: Settings
) -> tuple[pd.DataFrame, RecordedLoads]:
    """A cycle file (model.spectrum_files) as flights with their damage-equivalent ranges under
    the configured law, and their cycles."""
    flights, cycles = cycle_table(frame, source, settings.growth_law, settings.law().constants)
    recorded = np.full(len(flights), "cycles", dtype=object)
    tails = flights["tail"].to_numpy(dtype=object)
    return flights, RecordedLoads(
        tails, flights["flight_id"].to_numpy(dtype=object), recorded, cycles, {}
    )


def is_cycle_file(frame: pd.DataFrame) -> bool:
    """A flights upload that holds one row per cycle (it has a load_ratio column)."""
    return "load_ratio" in frame.columns


def store(session: Session, new: pd.DataFrame, recorded: RecordedLoads) -> None:
    """flight_spectra rows of the newly stored flights (`new`: the ingest's validated rows that
    were inserted, indexed by source row, with tail, flight_id and the id each was given,
    app.services.ingest with_ids) that recorded cycles; in the caller's transaction, as the
    flights are (app.storage.bulk: executemany on SQLite, one binary COPY on PostgreSQL).
    Each blob is a slice of the upload's one cycle buffer; no id is read back."""
    rows = new.index.to_numpy(dtype=np.int64) - 1
    chosen = recorded.recorded[rows] != None  # noqa: E711 - elementwise on an object array
    rows, inserted = rows[chosen], new[chosen]
    if not len(rows):
        return
    # internal invariant: the validated rows are the flights `recorded` describes, in order
    assert (recorded.flight_id[rows] == inserted["flight_id"].to_numpy(dtype=object)).all()
    assert (recorded.tail[rows] == inserted["tail"].to_numpy(dtype=object)).all()
    histories = [recorded.histories.get(int(row)) for row in rows]
    bulk(session.connection()).insert(
        FlightSpectrum.__table__,  # type: ignore[arg-type]
        {
            "flight_pk": inserted["id"].tolist(),
            "recorded": recorded.recorded[rows].tolist(),
            "cycles": recorded.cycles.packed(rows),
            "stress_history_mpa": [
                None if h is None else h.astype("<f8").tobytes() for h in histories
            ],
        },
    )


def stored(session: Session, aircraft_id: int, flight_id: str) -> Recorded | None:
    """What a stored flight recorded besides its range, None for a one-range flight."""
    row = session.execute(
        select(FlightSpectrum)
        .join(Flight, Flight.id == FlightSpectrum.flight_pk)
        .where(Flight.aircraft_id == aircraft_id, Flight.flight_id == flight_id)
    ).scalar_one_or_none()
    if row is None:
        return None
    history = (
        None
        if row.stress_history_mpa is None
        else np.frombuffer(row.stress_history_mpa, dtype="<f8").copy()
    )
    return Recorded(row.recorded, FlightCycles.unpacked(row.cycles), history)


# the load ratio's bins on the tail page: compressive-going, low, mid and high-mean cycles
R_BINS = ((-np.inf, 0.0, "R < 0"), (0.0, 0.3, "0 ≤ R < 0.3"), (0.3, 0.6, "0.3 ≤ R < 0.6"))
R_TOP = (0.6, "R ≥ 0.6")


@dataclass(frozen=True)
class SpectraSummary:
    """A tail's flights recorded as cycles: how many, their cycles per flight (mean, counting
    half cycles as half) and each load-ratio bin's share of the cycles."""

    flights: int
    cycles_per_flight: float
    load_ratio_mix: tuple[tuple[str, float], ...]


def summary(session: Session, aircraft_id: int) -> SpectraSummary | None:
    """The tail's SpectraSummary, None where no flight of it was recorded as cycles."""
    blobs = session.scalars(
        select(FlightSpectrum.cycles)
        .join(Flight, Flight.id == FlightSpectrum.flight_pk)
        .where(Flight.aircraft_id == aircraft_id)
    ).all()
    if not blobs:
        return None
    table = np.frombuffer(b"".join(blobs), dtype="<f8").reshape(-1, 3)
    ratio, count = table[:, 1], table[:, 2]
    total = float(count.sum())
    mix = [
        (label, float(count[(ratio >= low) & (ratio < high)].sum()) / total)
        for low, high, label in R_BINS
    ]
    mix.append((R_TOP[1], float(count[ratio >= R_TOP[0]].sum()) / total))
    return SpectraSummary(len(blobs), total / len(blobs), tuple(mix))
