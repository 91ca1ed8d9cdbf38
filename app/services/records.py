"""Stored flights and inspections read back in model.records' validated frame shapes."""

from __future__ import annotations

from collections.abc import Sequence

import pandas as pd
from sqlalchemy import String, select, type_coerce
from sqlalchemy.orm import Session

from app.tables import Aircraft, Flight, Inspection

_IN_LIST = 500


def _frame(session: Session, query: object, columns: list[str]) -> pd.DataFrame:
    rows = session.connection().execute(query).all()  # type: ignore[call-overload]
    return pd.DataFrame(rows, columns=columns)


def stored_flights(session: Session, aircraft_ids: Sequence[int]) -> pd.DataFrame:
    """Flights of these aircraft: tail, flight_id, flown_at (UTC), stress_range_mpa, mission."""
    columns = ["tail", "flight_id", "flown_at", "stress_range_mpa", "mission"]
    parts = []
    ids = list(aircraft_ids)
    for start in range(0, len(ids), _IN_LIST):
        query = (
            select(
                Aircraft.tail,
                Flight.flight_id,
                type_coerce(Flight.flown_at, String),  # parsed below, vectorised
                Flight.stress_range_mpa,
                Flight.mission,
            )
            .join(Aircraft, Aircraft.id == Flight.aircraft_id)
            .where(Flight.aircraft_id.in_(ids[start : start + _IN_LIST]))
        )
        parts.append(_frame(session, query, columns))
    frame = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=columns)
    frame["flown_at"] = pd.to_datetime(frame["flown_at"], utc=True, format="ISO8601").dt.as_unit(
        "ns"
    )
    frame["stress_range_mpa"] = frame["stress_range_mpa"].astype("float64")
    return frame


def stored_inspections(session: Session, aircraft_ids: Sequence[int]) -> pd.DataFrame:
    """Inspections of these aircraft: tail, inspection_id, inspected_at (UTC), crack_length_m."""
    columns = ["tail", "inspection_id", "inspected_at", "crack_length_m"]
    parts = []
    ids = list(aircraft_ids)
    for start in range(0, len(ids), _IN_LIST):
        query = (
            select(
                Aircraft.tail,
                Inspection.inspection_id,
                type_coerce(Inspection.inspected_at, String),
                Inspection.crack_length_m,
            )
            .join(Aircraft, Aircraft.id == Inspection.aircraft_id)
            .where(Inspection.aircraft_id.in_(ids[start : start + _IN_LIST]))
            .order_by(Aircraft.tail, Inspection.inspected_at, Inspection.inspection_id)
        )
        parts.append(_frame(session, query, columns))
    frame = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=columns)
    frame["inspected_at"] = pd.to_datetime(
        frame["inspected_at"], utc=True, format="ISO8601"
    ).dt.as_unit("ns")
    frame["crack_length_m"] = frame["crack_length_m"].astype("float64")
    return frame
