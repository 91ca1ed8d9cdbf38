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
from typing import Any

import numpy as np
import pandas as pd
from sqlalchemy import insert, select
from sqlalchemy.orm import Session

from app.config import Settings
from app.tables import Flight, FlightSpectrum
from model.cycle_counting import CycleError, FlightCycles, from_cycles, from_history
from model.records import RecordError

LOAD_FORMS = ("stress_range_mpa", "cycles", "stress_history_mpa")


@dataclass(frozen=True)
class Recorded:
    """What a flight recorded besides one range: its cycles and the history they came from."""

    recorded: str  # "cycles" or "stress_history"
    cycles: FlightCycles
    stress_history_mpa: np.ndarray | None = None


def with_ranges(
    flights: Sequence[dict[str, Any]], settings: Settings, source: str = "body"
) -> tuple[list[dict[str, Any]], dict[str, Recorded]]:
    """Each flight with its one stress_range_mpa (as sent, or its cycles' damage-equivalent
    range), and what the flights sent as cycles or histories recorded, by flight_id.  Raises
    RecordError (row: the flight's 1-based position) naming the flight and the field."""
    law = settings.law()
    out: list[dict[str, Any]] = []
    recorded: dict[str, Recorded] = {}
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
        recorded[str(name)] = entry
    return out, recorded


def store(session: Session, new: pd.DataFrame, recorded: Mapping[str, Recorded]) -> None:
    """flight_spectra rows of the newly stored flights (`new`: aircraft_id, flight_id) that
    recorded cycles; in the caller's transaction."""
    if not recorded or new.empty:
        return
    mine = new[new["flight_id"].isin(list(recorded))]
    rows = []
    for aircraft_id in pd.unique(mine["aircraft_id"]):
        flight_ids = mine.loc[mine["aircraft_id"] == aircraft_id, "flight_id"].tolist()
        query = select(Flight.id, Flight.flight_id).where(
            Flight.aircraft_id == int(aircraft_id), Flight.flight_id.in_(flight_ids)
        )
        for pk, flight_id in session.execute(query):
            entry = recorded[flight_id]
            history = entry.stress_history_mpa
            rows.append(
                {
                    "flight_pk": pk,
                    "recorded": entry.recorded,
                    "cycles": entry.cycles.packed(),
                    "stress_history_mpa": None
                    if history is None
                    else history.astype("<f8").tobytes(),
                }
            )
    if rows:
        session.execute(insert(FlightSpectrum), rows)


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
