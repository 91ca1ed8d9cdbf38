"""Stored flights and inspections read back in model.records' validated frame shapes."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import cast

import pandas as pd
from sqlalchemy import ClauseElement, Connection, String, select, type_coerce
from sqlalchemy.orm import Session
from sqlalchemy.sql.compiler import SQLCompiler

from app.tables import Aircraft, Flight, Inspection
from model import records

_IN_LIST = 500


def frame_of(connection: Connection, query: ClauseElement, columns: Sequence[str]) -> pd.DataFrame:
    """Run a SELECT on the driver's own cursor and build the frame column-wise.

    Bulk reads (millions of flights) skip SQLAlchemy's Row objects, whose per-row cost dominates
    at that size; the query must need no bind or result type processing (times come back in the
    driver's form, so callers select them through type_coerce(..., String) and parse them).
    """
    compiled = cast(
        SQLCompiler,
        query.compile(dialect=connection.dialect, compile_kwargs={"render_postcompile": True}),
    )
    params = compiled.construct_params()
    args = [params[k] for k in compiled.positiontup or []] if compiled.positional else params
    cursor = connection.connection.driver_connection.cursor()  # type: ignore[union-attr]
    try:
        cursor.execute(str(compiled), args)
        rows = cursor.fetchall()
    finally:
        cursor.close()
    values = list(zip(*rows, strict=True)) or [()] * len(columns)
    return pd.DataFrame(dict(zip(columns, values, strict=True)))


def _frame_by_aircraft(
    session: Session,
    aircraft_ids: Sequence[int],
    query_for: Callable[[list[int]], ClauseElement],
    columns: list[str],
) -> pd.DataFrame:
    """One query per chunk of aircraft ids (bounded IN lists), concatenated into one frame."""
    ids = list(aircraft_ids)
    parts = [
        frame_of(session.connection(), query_for(ids[start : start + _IN_LIST]), columns)
        for start in range(0, len(ids), _IN_LIST)
    ]
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=columns)


def _utc(times: pd.Series) -> pd.Series:
    """Stored ISO 8601 text (read as strings for speed), parsed vectorised to UTC nanoseconds."""
    return pd.to_datetime(times, utc=True, format="ISO8601").dt.as_unit("ns")


def stored_flights(session: Session, aircraft_ids: Sequence[int]) -> pd.DataFrame:
    """Flights of these aircraft: tail, flight_id, flown_at (UTC), stress_range_mpa, mission."""

    def query_for(ids: list[int]) -> ClauseElement:
        return (
            select(
                Aircraft.tail,
                Flight.flight_id,
                type_coerce(Flight.flown_at, String),
                Flight.stress_range_mpa,
                Flight.mission,
            )
            .join(Aircraft, Aircraft.id == Flight.aircraft_id)
            .where(Flight.aircraft_id.in_(ids))
        )

    columns = ["tail", "flight_id", "flown_at", "stress_range_mpa", "mission"]
    frame = _frame_by_aircraft(session, aircraft_ids, query_for, columns)
    frame["flown_at"] = _utc(frame["flown_at"])
    frame["stress_range_mpa"] = frame["stress_range_mpa"].astype("float64")
    return frame


INSPECTION_COLUMNS = [*records.INSPECTION_COLUMNS, *records.INSPECTION_OPTIONAL_COLUMNS]


def stored_inspections(session: Session, aircraft_ids: Sequence[int]) -> pd.DataFrame:
    """Inspections of these aircraft in validate_inspections' shape with every optional column:
    tail, inspection_id, inspected_at (UTC), crack_length_m (NaN: not detected), detected,
    detection_threshold_m, pod_a50_m, pod_a90_m, repaired, crack_after_repair_m."""

    def query_for(ids: list[int]) -> ClauseElement:
        return (
            select(
                Aircraft.tail,
                Inspection.inspection_id,
                type_coerce(Inspection.inspected_at, String),
                Inspection.crack_length_m,
                Inspection.detected,
                Inspection.detection_threshold_m,
                Inspection.pod_a50_m,
                Inspection.pod_a90_m,
                Inspection.repaired,
                Inspection.crack_after_repair_m,
            )
            .join(Aircraft, Aircraft.id == Inspection.aircraft_id)
            .where(Inspection.aircraft_id.in_(ids))
            .order_by(Aircraft.tail, Inspection.inspected_at, Inspection.inspection_id)
        )

    frame = _frame_by_aircraft(session, aircraft_ids, query_for, INSPECTION_COLUMNS)
    frame["inspected_at"] = _utc(frame["inspected_at"])
    for flag in ("detected", "repaired"):
        frame[flag] = frame[flag].astype(bool)
    for number in INSPECTION_COLUMNS[3:]:
        if number not in ("detected", "repaired"):
            frame[number] = frame[number].astype("float64")
    return frame
