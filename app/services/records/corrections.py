"""Stored flights and inspections one at a time: read, correct, delete (a wrong record put right).

A correction merges the changed fields into the stored record and checks the result as any new
record is checked (the file contract of model.records, the bounds of app.services.records.plausibility);
a corrected inspection is compared with its tail's forecast again (app.services.forecasts.assessment).
Corrections and deletions are audited with the record as it was, and drop the tail's cached
forecasts (forecast_cache.invalidate), so its next forecast re-marches it.  Each write is
guarded by the record's audit_id as read (compare and swap): of two corrections of one record
made at the same moment, the second finds it changed and gets a 409 instead of overwriting a
version it never saw.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

import numpy as np
import pandas as pd
from sqlalchemy import delete, select, update
from sqlalchemy.orm import Session

from app.config import Settings
from app.errors import ConflictError, NotFoundError
from app.services import audit
from app.services.forecasts import assessment, forecast_cache
from app.services.records import ingest, plausibility, spectra
from app.services.records.aircraft import find_aircraft
from app.services.records.stored_records import FLIGHTS, INSPECTIONS, RecordKind
from app.tables import Flight, Inspection
from model.record_validation import validate_flights, validate_inspections
from model.records import RecordError

Row = Flight | Inspection


def _find(session: Session, kind: RecordKind, tail: str, key: str) -> Row:
    aircraft = find_aircraft(session, tail)
    table = kind.table
    row: Row | None = session.scalars(
        select(table).where(table.aircraft_id == aircraft.id, getattr(table, kind.key) == key)
    ).one_or_none()  # type: ignore[assignment]
    if row is None:
        raise NotFoundError(f"tail {tail!r} has no {kind.key} {key!r}")
    return row


def get_flight(session: Session, tail: str, flight_id: str) -> Flight:
    """One stored flight; raises NotFoundError (unknown tail or flight)."""
    row = _find(session, FLIGHTS, tail, flight_id)
    assert isinstance(row, Flight)
    return row


def get_inspection(session: Session, tail: str, inspection_id: str) -> Inspection:
    """One stored inspection; raises NotFoundError (unknown tail or inspection)."""
    row = _find(session, INSPECTIONS, tail, inspection_id)
    assert isinstance(row, Inspection)
    return row


def as_record(kind: RecordKind, row: Row) -> dict[str, Any]:
    """The record's key and values, JSON-ready (times in ISO 8601)."""
    out: dict[str, Any] = {kind.key: getattr(row, kind.key)}
    for name in kind.values:
        value = getattr(row, name)
        out[name] = value.isoformat() if isinstance(value, datetime) else value
    return out


def _checked(
    kind: RecordKind, tail: str, record: dict[str, Any], settings: Settings, cycled: bool
) -> pd.DataFrame:
    """The merged record as a validated one-row frame; raises RecordError (source "body").
    cycled: a flight whose range is its stored cycles' damage-equivalent one (bounded by cycle
    when they were sent, app.services.records.plausibility.check_flights)."""
    bounds = plausibility.Bounds.of(settings)
    if kind is FLIGHTS:
        frame = validate_flights(ingest.flights_frame(tail, [record]), "body")
        plausibility.check_flights(frame, "body", bounds, cycled=np.array([cycled]))
        return frame
    frame = validate_inspections(ingest.inspections_frame(tail, [record]), "body")
    plausibility.check_inspections(frame, "body", bounds)
    return frame


def _correct(
    session: Session,
    kind: RecordKind,
    tail: str,
    key: str,
    changes: dict[str, Any],
    *,
    actor: audit.Actor,
    settings: Settings,
    cycled: bool = False,
) -> Row:
    row = _find(session, kind, tail, key)
    row_id, aircraft_id, old_audit = row.id, row.aircraft_id, row.audit_id
    unknown = set(changes) - set(kind.values)
    if unknown:
        raise ValueError(f"not a field of a stored {kind.noun[:-1]}: {sorted(unknown)}")
    if not changes:
        return row  # nothing to correct: no write, no audit event
    before = as_record(kind, row)
    merged = {**{name: getattr(row, name) for name in kind.values}, **changes, kind.key: key}
    frame = _checked(kind, tail, merged, settings, cycled)
    values: dict[str, Any] = {name: getattr(row, name) for name in kind.values}
    for name in kind.values:
        value = frame.iloc[0][name] if name in frame.columns else merged.get(name)
        values[name] = _python(value)
    if isinstance(row, Inspection):  # compared with its own location's forecast
        assessed = assessment.assess(session, frame.assign(location_id=row.location_id), settings)
        values.update({name: _python(assessed.iloc[0][name]) for name in assessment.COLUMNS})
    session.rollback()  # the comparison may have read (and cached); the write starts afresh
    table = kind.table
    event = audit.record(
        session,
        actor,
        f"{kind.noun[:-1]}.correct",
        f"{tail}/{key}",
        {"before": before, "changes": sorted(changes)},
    )
    changed = session.execute(
        update(table)
        .where(table.id == row_id, table.audit_id.is_not_distinct_from(old_audit))
        .values(**values, audit_id=event)
    )
    if changed.rowcount != 1:  # type: ignore[attr-defined]
        session.rollback()
        raise ConflictError(f"{kind.key} {key!r} of tail {tail!r} changed meanwhile; read it again")
    forecast_cache.invalidate(session, [aircraft_id])
    session.commit()
    session.refresh(row)
    return row


def _delete(session: Session, kind: RecordKind, tail: str, key: str, *, actor: audit.Actor) -> Row:
    row = _find(session, kind, tail, key)
    table = kind.table
    audit.record(
        session,
        actor,
        f"{kind.noun[:-1]}.delete",
        f"{tail}/{key}",
        {"before": as_record(kind, row)},
    )
    block = spectra.block_of(session, row.id) if isinstance(row, Flight) else None
    gone = session.execute(
        delete(table).where(table.id == row.id, table.audit_id.is_not_distinct_from(row.audit_id))
    )
    if gone.rowcount != 1:  # type: ignore[attr-defined]
        session.rollback()
        raise ConflictError(f"{kind.key} {key!r} of tail {tail!r} changed meanwhile; read it again")
    if block is not None:
        spectra.drop_unreferenced(session, row.aircraft_id, block)
    forecast_cache.invalidate(session, [row.aircraft_id])
    session.commit()
    return row


def _python(value: Any) -> Any:
    """A frame cell as the driver takes it: NaN as None, Timestamps as datetimes."""
    if isinstance(value, pd.Timestamp):
        return value.to_pydatetime()
    if value is None or (not isinstance(value, str) and pd.isna(value)):
        return None
    return value.item() if hasattr(value, "item") else value


def correct_flight(
    session: Session,
    tail: str,
    flight_id: str,
    changes: dict[str, Any],
    *,
    actor: audit.Actor,
    settings: Settings,
) -> Flight:
    """Change some of a flight's values (flown_at, stress_range_mpa, mission); raises
    NotFoundError, RecordError (the corrected flight is invalid, or its range is its recorded
    cycles' and cannot be set apart from them) or ConflictError."""
    flight = get_flight(session, tail, flight_id)
    cycled = spectra.block_of(session, flight.id) is not None
    if changes.get("stress_range_mpa") is not None and cycled:
        raise RecordError(
            "body",
            None,
            "stress_range_mpa",
            f"flight {flight_id!r} was recorded as cycles and its range is theirs: "
            "delete it and send its corrected cycles",
        )
    row = _correct(
        session, FLIGHTS, tail, flight_id, changes, actor=actor, settings=settings, cycled=cycled
    )
    assert isinstance(row, Flight)
    return row


def correct_inspection(
    session: Session,
    tail: str,
    inspection_id: str,
    changes: dict[str, Any],
    *,
    actor: audit.Actor,
    settings: Settings,
) -> Inspection:
    """Change some of an inspection's values (any but its id); the result is checked as a new
    inspection is (combinations, bounds) and compared with the forecast again."""
    row = _correct(
        session, INSPECTIONS, tail, inspection_id, changes, actor=actor, settings=settings
    )
    assert isinstance(row, Inspection)
    return row


def delete_flight(session: Session, tail: str, flight_id: str, *, actor: audit.Actor) -> Flight:
    """Remove a flight (audited with its values); returns it as it was."""
    row = _delete(session, FLIGHTS, tail, flight_id, actor=actor)
    assert isinstance(row, Flight)
    return row


def delete_inspection(
    session: Session, tail: str, inspection_id: str, *, actor: audit.Actor
) -> Inspection:
    """Remove an inspection (audited with its values); returns it as it was."""
    row = _delete(session, INSPECTIONS, tail, inspection_id, actor=actor)
    assert isinstance(row, Inspection)
    return row
