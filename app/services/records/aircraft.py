"""Aircraft registry: create or update a tail, list tails with their record counts."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import Select, delete, func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.errors import NotFoundError
from app.services import audit
from app.services.forecasts.forecast_cache import invalidate
from app.services.records import plausibility
from app.tables import Aircraft, Flight, Inspection


@dataclass(frozen=True)
class AircraftSummary:
    tail: str
    initial_crack_m: float | None
    created_at: datetime
    flight_count: int
    last_flown_at: datetime | None
    inspection_count: int


def _summaries() -> Select[tuple[Aircraft, int, datetime | None, int]]:
    # Correlated subqueries use the (aircraft_id, ...) unique indexes: cheap for a page of tails.
    flight_count = (
        select(func.count(Flight.id)).where(Flight.aircraft_id == Aircraft.id).scalar_subquery()
    )
    last_flown = (
        select(func.max(Flight.flown_at)).where(Flight.aircraft_id == Aircraft.id).scalar_subquery()
    )
    inspection_count = (
        select(func.count(Inspection.id))
        .where(Inspection.aircraft_id == Aircraft.id)
        .scalar_subquery()
    )
    return select(Aircraft, flight_count, last_flown, inspection_count)


def _summary(row: Any) -> AircraftSummary:
    aircraft, flights, last_flown, inspections = row
    return AircraftSummary(
        aircraft.tail,
        aircraft.initial_crack_m,
        aircraft.created_at,
        flights,
        last_flown,
        inspections,
    )


def find_aircraft(session: Session, tail: str) -> Aircraft:
    """The aircraft with this tail; raises NotFoundError."""
    aircraft = session.scalars(select(Aircraft).where(Aircraft.tail == tail)).one_or_none()
    if aircraft is None:
        raise NotFoundError(f"unknown tail {tail!r}")
    return aircraft


def get_aircraft(session: Session, tail: str) -> AircraftSummary:
    row = session.execute(_summaries().where(Aircraft.tail == tail)).one_or_none()
    if row is None:
        raise NotFoundError(f"unknown tail {tail!r}")
    return _summary(row)


def list_aircraft(
    session: Session, *, limit: int, offset: int
) -> tuple[list[AircraftSummary], int]:
    """A page of aircraft ordered by tail, and the total number of aircraft."""
    total = session.scalar(select(func.count(Aircraft.id))) or 0
    rows = session.execute(_summaries().order_by(Aircraft.tail).limit(limit).offset(offset))
    return [_summary(row) for row in rows], total


def put_aircraft(
    session: Session,
    tail: str,
    *,
    initial_crack_m: float | None,
    actor: audit.Actor,
    bounds: plausibility.Bounds,
) -> tuple[AircraftSummary, bool]:
    """Create the tail or update it; True when created.  A new initial crack voids its forecasts.
    Creations and changes are audited (with the initial crack before).  Raises RecordError for
    an initial crack at or beyond the critical one.

    An upsert under concurrency: requests creating the same new tail at once all find it
    missing, one stores it and the others' inserts break the unique tail; those roll back and
    update the stored tail instead (the last request's initial crack stays, as for any PUT)."""
    plausibility.check_initial_crack(initial_crack_m, bounds, "body")
    try:
        return _put(session, tail, initial_crack_m, actor)
    except IntegrityError:
        session.rollback()
    return _put(session, tail, initial_crack_m, actor)


def _put(
    session: Session, tail: str, initial_crack_m: float | None, actor: audit.Actor
) -> tuple[AircraftSummary, bool]:
    aircraft = session.scalars(select(Aircraft).where(Aircraft.tail == tail)).one_or_none()
    created = aircraft is None
    if aircraft is None:
        session.add(Aircraft(tail=tail, initial_crack_m=initial_crack_m))
        audit.record(session, actor, "aircraft.create", tail, {"initial_crack_m": initial_crack_m})
    elif aircraft.initial_crack_m != initial_crack_m:
        before = aircraft.initial_crack_m
        aircraft.initial_crack_m = initial_crack_m
        invalidate(session, [aircraft.id])
        audit.record(
            session,
            actor,
            "aircraft.update",
            tail,
            {"before": {"initial_crack_m": before}, "after": {"initial_crack_m": initial_crack_m}},
        )
    session.commit()
    return get_aircraft(session, tail), created


def delete_aircraft(session: Session, tail: str, *, actor: audit.Actor) -> AircraftSummary:
    """Remove the tail with its flights, inspections and cached forecasts (the database's
    cascades and the flights' triggers, migration 9c4d2e7f1a30), audited with what it held;
    returns the tail as it was.  Raises NotFoundError."""
    summary = get_aircraft(session, tail)
    aircraft = find_aircraft(session, tail)
    audit.record(
        session,
        actor,
        "aircraft.delete",
        tail,
        {
            "initial_crack_m": summary.initial_crack_m,
            "flights": summary.flight_count,
            "inspections": summary.inspection_count,
        },
    )
    session.execute(delete(Aircraft).where(Aircraft.id == aircraft.id))
    session.commit()
    return summary
