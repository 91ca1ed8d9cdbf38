"""DELETE /locations/{name}: a catalogue entry leaves only when nothing refers to it (aircraft
that list it, inspections at it, model versions of it, retrains queued for it), else a 409 says
what does; `force` removes those records first, after an audit entry of what it removes.  A
typo or a tour's example entry need not stay forever, and no record is orphaned silently.

Aircraft that list no subset carry the whole catalogue; they simply stop carrying it.  Its
cached forecast rows are derived data and go with it (the database's cascade).
"""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import delete, func, select, update
from sqlalchemy.orm import Session

from app.errors import ConflictError
from app.services import audit
from app.services.records import locations
from app.tables import (
    DEFAULT_LOCATION,
    Aircraft,
    AircraftLocation,
    Inspection,
    Job,
    Location,
    ModelVersion,
    utc_now,
)


@dataclass(frozen=True)
class References:
    """What refers to a location: tails listing it, its inspections, its versions, and its
    retrain jobs not finished."""

    tails: list[str]
    inspections: int
    versions: list[int]
    jobs: list[str]

    def said(self) -> str:
        """The references in words, for the 409."""
        parts = []
        if self.tails:
            shown = ", ".join(self.tails[:5]) + (" ..." if len(self.tails) > 5 else "")
            parts.append(f"{len(self.tails)} aircraft list it ({shown}: PUT their locations)")
        if self.inspections:
            parts.append(f"{self.inspections} inspections are stored at it")
        if self.versions:
            parts.append(f"model versions {', '.join(f'v{v}' for v in self.versions)} serve it")
        if self.jobs:
            parts.append(f"retrain jobs {', '.join(self.jobs)} are queued or running for it")
        return "; ".join(parts)

    @property
    def none(self) -> bool:
        return not (self.tails or self.inspections or self.versions or self.jobs)


def references(session: Session, location_id: int, name: str) -> References:
    """Everything that refers to the location."""
    tails = session.scalars(
        select(Aircraft.tail)
        .join(AircraftLocation, AircraftLocation.aircraft_id == Aircraft.id)
        .where(AircraftLocation.location_id == location_id)
        .order_by(Aircraft.tail)
    ).all()
    inspections = session.scalar(
        select(func.count(Inspection.id)).where(Inspection.location_id == location_id)
    )
    versions = session.scalars(
        select(ModelVersion.version)
        .where(ModelVersion.location_id == location_id)
        .order_by(ModelVersion.version)
    ).all()
    unfinished = session.scalars(
        select(Job).where(Job.kind == "retrain", Job.status.in_(("queued", "running")))
    ).all()
    jobs = [job.id for job in unfinished if (job.params or {}).get("location") == name]
    return References(list(tails), int(inspections or 0), list(versions), jobs)


def delete_location(
    session: Session, name: str, *, force: bool, actor: audit.Actor
) -> locations.StoredLocation:
    """Remove the catalogue entry `name`, audited with the entry and what went with it;
    returns the entry as it was.  Raises NotFoundError (unknown), ConflictError (the default
    location, or records refer to it and `force` is not set: the error says which).  force:
    remove the tails' listings of it, its inspections and its model versions (their cached
    rows with them) first.  Commits."""
    if name == DEFAULT_LOCATION:
        raise ConflictError(
            f"the {DEFAULT_LOCATION!r} location cannot be deleted: every request that names no "
            "location is its"
        )
    entry = locations.get_location(session, name)
    found = references(session, entry.id, name)
    if not found.none and not force:
        raise ConflictError(
            f"location {name!r} is still referred to: {found.said()}; "
            "DELETE with ?force=true removes these records with it"
        )
    detail = {
        "entry": {field: getattr(entry, field) for field in locations.FIELDS},
        "removed": {
            "tails_listing": found.tails,
            "inspections": found.inspections,
            "model_versions": found.versions,
            "jobs_cancelled": found.jobs,
        },
    }
    audit.record(session, actor, "location.delete", name, detail)
    queued = (Job.id.in_(found.jobs)) & (Job.status == "queued")
    session.execute(update(Job).where(queued).values(status="cancelled", finished_at=utc_now()))
    session.execute(update(Job).where(Job.id.in_(found.jobs)).values(cancel_requested=True))
    session.execute(delete(AircraftLocation).where(AircraftLocation.location_id == entry.id))
    session.execute(delete(Inspection).where(Inspection.location_id == entry.id))
    # their cached rows go by the database's cascade
    session.execute(delete(ModelVersion).where(ModelVersion.location_id == entry.id))
    session.execute(delete(Location).where(Location.id == entry.id))
    session.commit()
    return entry
