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

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import pandas as pd
from sqlalchemy import ClauseElement, select
from sqlalchemy.orm import Session

from app.config import Settings
from app.storage import BulkStorage
from app.tables import Flight, FlightSpectrum
from model.cycle_counting import CycleError, FlightCycles, from_cycles, from_history
from model.records import RecordError
from model.spectrum_files import cycles_to_flights

LOAD_FORMS = ("stress_range_mpa", "cycles", "stress_history_mpa")


class Recorded(NamedTuple):
    """What a flight recorded besides one range: its cycles and the history they came from (a
    tuple: a cycle file makes one per flight, millions of them)."""

    recorded: str  # "cycles" or "stress_history"
    cycles: FlightCycles
    stress_history_mpa: np.ndarray | None = None


Key = tuple[str, str]  # (tail, flight_id)


def with_ranges(
    tail: str, flights: Sequence[dict[str, Any]], settings: Settings, source: str = "body"
) -> tuple[list[dict[str, Any]], dict[Key, Recorded]]:
    """Each flight of `tail` with its one stress_range_mpa (as sent, or its cycles'
    damage-equivalent range), and what the flights sent as cycles or histories recorded, by
    (tail, flight_id).  Raises RecordError (row: the flight's 1-based position) naming the
    flight and the field."""
    law = settings.law()
    out: list[dict[str, Any]] = []
    recorded: dict[Key, Recorded] = {}
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
            continue
        try:
            if given[0] == "cycles":
                cycles = from_cycles(flight["cycles"])
                entry = Recorded("cycles", cycles)
            else:
                cycles = from_history(flight["stress_history_mpa"])
                history = np.asarray(flight["stress_history_mpa"], dtype=np.float64)
                entry = Recorded("stress_history", cycles, history)
        except CycleError as exc:
            raise RecordError(source, row, exc.field, f"flight {name!r}: {exc}") from exc
        equivalent = cycles.equivalent_range(settings.growth_law, law.constants)
        out.append({**flight, "stress_range_mpa": equivalent})
        recorded[(tail, str(name))] = entry
    return out, recorded


def from_cycle_file(
    frame: pd.DataFrame, source: str, settings: Settings
) -> tuple[pd.DataFrame, dict[Key, Recorded]]:
    """A cycle file (model.spectrum_files) as flights with their damage-equivalent ranges under
    the configured law, and their cycles by (tail, flight_id)."""
    flights, cycles = cycles_to_flights(
        frame, source, settings.growth_law, settings.law().constants
    )
    return flights, {key: Recorded("cycles", value) for key, value in cycles.items()}


def is_cycle_file(frame: pd.DataFrame) -> bool:
    """A flights upload that holds one row per cycle (it has a load_ratio column)."""
    return "load_ratio" in frame.columns


def store(session: Session, new: pd.DataFrame, recorded: Mapping[Key, Recorded]) -> None:
    """flight_spectra rows of the newly stored flights (`new`: tail, aircraft_id, flight_id)
    that recorded cycles; in the caller's transaction, through the driver's executemany (the
    portable bulk path: a cycle file holds a row per flight)."""
    if not recorded or new.empty:
        return
    tails = dict(zip(new["aircraft_id"].tolist(), new["tail"].tolist(), strict=True))
    fresh = set(zip(new["tail"].tolist(), new["flight_id"].tolist(), strict=True))
    store = BulkStorage(session.connection())

    def query_for(ids: list[int]) -> ClauseElement:
        return select(Flight.id, Flight.aircraft_id, Flight.flight_id).where(
            Flight.aircraft_id.in_(ids)
        )

    flights = store.frame_in(list(tails), query_for, ["pk", "aircraft_id", "flight_id"])
    columns: dict[str, list[Any]] = {
        "flight_pk": [],
        "recorded": [],
        "cycles": [],
        "stress_history_mpa": [],
    }
    for pk, aircraft_id, flight_id in flights.itertuples(index=False):
        key = (tails[aircraft_id], flight_id)
        entry = recorded.get(key)
        if entry is None or key not in fresh:  # a one-range flight, or one stored before
            continue
        history = entry.stress_history_mpa
        columns["flight_pk"].append(int(pk))
        columns["recorded"].append(entry.recorded)
        columns["cycles"].append(entry.cycles.packed())
        columns["stress_history_mpa"].append(
            None if history is None else history.astype("<f8").tobytes()
        )
    store.insert(FlightSpectrum.__table__, columns)  # type: ignore[arg-type]


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
