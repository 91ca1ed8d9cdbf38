"""What an aircraft's answer cannot weigh, or weighs on the fleet's evidence alone, with the
reason: a carried location without an active version (none trained yet, or its latest version
is a candidate the gate refused), and one the tail was never inspected at (its forecast is the
fleet's, its growth drawn from the fleet's prior).  A structures engineer reads these beside
the governing location, so that a location is never silently left out."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from sqlalchemy import exists, select
from sqlalchemy.orm import Session

from app.errors import ConflictError
from app.services.models import latest_version_words
from app.tables import Aircraft, AircraftLocation, Inspection, Location, ModelVersion


@dataclass(frozen=True)
class LocationNote:
    """A carried location the aircraft's answer leaves out (no active version) or forecasts
    from the fleet alone (never inspected on this tail), and why, in words."""

    location: str
    reason: str


NEVER_INSPECTED = (
    "never inspected at this location: its forecast is the fleet's, the tail's growth drawn "
    "from the fleet's spread (record an inspection to condition it on this tail)"
)


def _unassessed_reason(latest: int | None, status: str | None) -> str:
    if latest is None:
        return (
            "no active model version: no retrain has trained this location yet "
            "(POST /models/retrain trains every location an aircraft with flights carries)"
        )
    return f"no active model version: {latest_version_words(latest, str(status))}"


def notes(
    session: Session,
    aircraft_id: int,
    lines: Sequence[tuple[str, int, int | None, int | None]],
    *,
    inspected_too: bool,
) -> tuple[LocationNote, ...]:
    """The notes of the tail's carried locations (app.services.forecasts.aircraft_summary.Carried.lines:
    name, id, active version, stamp), by name, in one query.  inspected_too: also name the
    locations with an active version that the tail was never inspected at (an aircraft's
    summary of several locations; a one-location answer says it in its data age)."""
    if not lines or (not inspected_too and all(v is not None for _, _, v, _ in lines)):
        return ()  # nothing to note, nothing to read (a kept answer checks it on every request)
    newest = (
        select(ModelVersion.version, ModelVersion.status)
        .where(ModelVersion.location_id == Location.id)
        .order_by(ModelVersion.version.desc())
        .limit(1)
        .correlate(Location)
    )
    latest = newest.with_only_columns(ModelVersion.version).scalar_subquery()
    status = newest.with_only_columns(ModelVersion.status).scalar_subquery()
    inspected = exists().where(
        Inspection.aircraft_id == aircraft_id, Inspection.location_id == Location.id
    )
    rows = session.execute(
        select(Location.id, latest, status, inspected).where(
            Location.id.in_([ident for _, ident, _, _ in lines])
        )
    ).all()
    facts = {ident: (version, state, seen) for ident, version, state, seen in rows}
    out = []
    for name, ident, version, _ in lines:
        newest, state, seen = facts[ident]
        if version is None:
            out.append(LocationNote(name, _unassessed_reason(newest, state)))
        elif inspected_too and not seen:
            out.append(LocationNote(name, NEVER_INSPECTED))
    return tuple(out)


def fleet_unassessed(session: Session) -> list[LocationNote]:
    """The catalogue's locations some aircraft carries that have no active version, by name,
    each with why (the fleet page's banner: their rows are in no ranking)."""
    newest = (
        select(ModelVersion.version, ModelVersion.status)
        .where(ModelVersion.location_id == Location.id)
        .order_by(ModelVersion.version.desc())
        .limit(1)
        .correlate(Location)
    )
    active = exists().where(
        ModelVersion.location_id == Location.id, ModelVersion.status == "active"
    )
    # (app.services.records.carriage.carries, turned round: some aircraft lists it, or lists none)
    lists_none = ~exists().where(AircraftLocation.aircraft_id == Aircraft.id)
    carried = exists().where(AircraftLocation.location_id == Location.id) | exists(
        select(Aircraft.id).where(lists_none)
    )
    rows = session.execute(
        select(
            Location.name,
            newest.with_only_columns(ModelVersion.version).scalar_subquery(),
            newest.with_only_columns(ModelVersion.status).scalar_subquery(),
        )
        .where(~active, carried)
        .order_by(Location.name)
    ).all()
    return [LocationNote(name, _unassessed_reason(latest, state)) for name, latest, state in rows]


def no_model_anywhere(tail: str, found: Sequence[LocationNote]) -> ConflictError:
    """The error of an aircraft none of whose carried locations has an active version."""
    said = "; ".join(f"{note.location}: {note.reason}" for note in found)
    return ConflictError(
        f"no model is active at any location tail {tail!r} carries ({said or 'it carries none'})"
    )
