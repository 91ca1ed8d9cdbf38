"""The pages' one door to the services: every forecast, model and job read goes through here.

The forecast service is being split into modules; only this file names where its functions
live.  Nothing here computes a forecast beyond what the JSON routes do: the fleet page reads the
cached ranking (app.services.ranking.order.ranking), a tail page one cached forecast.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import date, datetime

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app import tables
from app.config import Settings
from app.services import models as model_service
from app.services.forecasts import aircraft_summary, location_notes
from app.services.forecasts import crack_history as history_service
from app.services.forecasts import forecast as forecast_service
from app.services.jobs import queue as job_service
from app.services.ranking import location_ranking
from app.services.ranking import order as ranking_service
from app.services.records import aircraft_locations, carriage, locations, stored
from app.services.records import spectra as spectra_service
from app.services.records.aircraft import find_aircraft
from app.services.records.ingest import list_inspections
from app.tables import Flight, Inspection, Job

RankedTail = ranking_service.RankedTail
DEFAULT_LOCATION = tables.DEFAULT_LOCATION
TailForecast = forecast_service.TailForecast

# The fleet page shows every tail; the JSON route allows this many at most.
_ALL_TAILS = 10_000


@dataclass(frozen=True)
class FleetRanking:
    model_version: int
    critical_crack_m: float
    horizon_days: int
    as_of: date
    tails: list[RankedTail]


@dataclass(frozen=True)
class LoadsSummary:
    """A tail's recorded loads: all flights, their rate and the stress range's spread."""

    flights: int
    first_flown_at: datetime | None
    last_flown_at: datetime | None
    flights_per_day: float | None
    stress_mean_mpa: float | None
    stress_p95_mpa: float | None
    # flights recorded as cycles (app.services.records.spectra): their count, cycles per flight and
    # load-ratio mix; None where none was
    spectra: spectra_service.SpectraSummary | None = None


def fleet_ranking(
    session: Session, settings: Settings, *, horizon_days: int, as_of: date | None = None
) -> FleetRanking:
    """Every tail by risk over the horizon after as_of (default settings.today(); the JSON
    ranking's cached values): (tail, location) rows, an aircraft's together, once several
    locations have models.  Raises ConflictError without an active model."""
    as_of = as_of or settings.today()
    version, critical, _, items = location_ranking.ranking(
        session,
        limit=_ALL_TAILS,
        settings=settings,
        horizon_days=horizon_days,
        by="risk",
        as_of=as_of,
    )
    return FleetRanking(version, critical, horizon_days, as_of, items)


def top_tails(
    session: Session, settings: Settings, *, top: int, horizon_days: int, as_of: date | None
) -> list[str]:
    """The `top` tails by risk as of `as_of` (None: settings.today()): aircraft, each once
    (by its governing row where several locations have models)."""
    _, _, _, items = location_ranking.ranking(
        session,
        limit=top * max(1, len(model_service.active_versions(session))),
        settings=settings,
        horizon_days=horizon_days,
        by="risk",
        as_of=as_of,
    )
    return list(dict.fromkeys(item.tail for item in items))[:top]


def tail_forecast(
    session: Session,
    tail: str,
    settings: Settings,
    *,
    horizon_days: int,
    as_of: date | None,
    location: str | None = None,
) -> TailForecast:
    """The JSON forecast route's answer (of the location, default the default one) as of
    `as_of` (None: settings.today()).  Raises NotFoundError, ConflictError."""
    return forecast_service.forecast_tail(
        session, tail, horizon_days=horizon_days, settings=settings, as_of=as_of, location=location
    )


def aircraft_forecast(
    session: Session, tail: str, settings: Settings, *, horizon_days: int, as_of: date | None
) -> tuple[str, TailForecast]:
    """The location whose forecast the aircraft's answer is (the default one, or the governing
    one where the tail carries no default with a model: aircraft_summary.aircraft_location)
    and that forecast.  Raises NotFoundError, ConflictError."""
    as_of = as_of or settings.today()
    location = aircraft_summary.aircraft_location(
        session, tail, horizon_days=horizon_days, as_of=as_of, settings=settings
    )
    shown = tail_forecast(
        session, tail, settings, horizon_days=horizon_days, as_of=as_of, location=location
    )
    return location or DEFAULT_LOCATION, shown


def carried_locations(session: Session, tail: str) -> list[str]:
    """The locations the tail carries, by name.  Raises NotFoundError."""
    return aircraft_locations.carried(session, tail)


def tail_history(
    session: Session, tail: str, settings: Settings, location: str | None = None
) -> history_service.CrackHistory:
    """The tail's estimated crack over its recorded flights at the location.  Raises
    NotFoundError, ConflictError."""
    return history_service.crack_history(session, tail, settings, location=location)


def catalogue(session: Session) -> list[locations.StoredLocation]:
    """Every catalogue entry, as GET /locations lists them."""
    return locations.list_locations(session)


def carriers(session: Session, entries: list[locations.StoredLocation]) -> dict[str, int]:
    """How many aircraft carry each catalogue entry, by name."""
    counts = carriage.carrier_counts(session, [entry.id for entry in entries])
    return {entry.name: counts[entry.id] for entry in entries}


def active_locations(session: Session) -> list[str]:
    """Every location with an active version (the default one included), by name."""
    names = locations.names_of(session, list(model_service.active_versions(session)))
    return sorted(names.values())


def tail_location_notes(session: Session, tail: str) -> list[location_notes.LocationNote]:
    """The aircraft answer's notes: carried locations without a model, and (with several
    locations) those the tail was never inspected at, each with why."""
    carried = aircraft_summary.its_locations(session, tail)
    if carried.aircraft_id is None:
        return []
    return list(
        location_notes.notes(
            session, carried.aircraft_id, carried.lines, inspected_too=carried.several
        )
    )


def fleet_unassessed(session: Session) -> list[location_notes.LocationNote]:
    """The carried locations without an active version, fleet-wide, each with why."""
    return location_notes.fleet_unassessed(session)


def unassessed_locations(session: Session, tail: str) -> list[str]:
    """The locations the tail carries without an active version: no chart, no risk shown."""
    return aircraft_locations.unassessed(session, tail)


def location_of_inspections(session: Session, rows: list[Inspection]) -> dict[int, str]:
    """Each inspection row's location name, by row id."""
    names = locations.names_of(session, [row.location_id for row in rows])
    return {row.id: names[row.location_id] for row in rows}


def tail_inspections(session: Session, tail: str) -> list[Inspection]:
    """The tail's inspections in time order.  Raises NotFoundError."""
    return list_inspections(session, find_aircraft(session, tail).id)


def loads_summary(session: Session, tail: str) -> LoadsSummary:
    """Counts and stress statistics of every recorded flight of the tail.  Raises NotFoundError."""
    aircraft = find_aircraft(session, tail)
    mine = Flight.aircraft_id == aircraft.id
    count, first, last = session.execute(
        select(func.count(Flight.id), func.min(Flight.flown_at), func.max(Flight.flown_at)).where(
            mine
        )
    ).one()
    if not count:
        return LoadsSummary(0, None, None, None, None, None)
    stress = np.fromiter(
        session.scalars(select(Flight.stress_range_mpa).where(mine)), dtype=np.float64
    )  # (flights,)
    days = (last - first).total_seconds() / 86_400
    return LoadsSummary(
        flights=count,
        first_flown_at=first,
        last_flown_at=last,
        flights_per_day=count / days if days > 0 else None,
        stress_mean_mpa=float(stress.mean()),
        stress_p95_mpa=float(np.percentile(stress, 95)),
        spectra=spectra_service.summary(session, aircraft.id),
    )


def active_version(session: Session) -> int | None:
    return model_service.active_version_number(session)


def model_versions(session: Session) -> list[stored.StoredVersion]:
    """Every stored version, newest first, each with its location."""
    return list(reversed(stored.versions(session, model_service.list_versions(session))))


def active_by_location(session: Session) -> list[tuple[str, int]]:
    """(location, active version) of every location with one, by name."""
    active = model_service.active_versions(session)
    names = locations.names_of(session, list(active))
    return sorted((names[ident], version) for ident, version in active.items())


def recent_jobs(session: Session, *, limit: int) -> list[Job]:
    return job_service.list_jobs(session, limit=limit)
