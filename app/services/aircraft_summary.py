"""Decisions per aircraft: every location's forecast in one line, and the governing one.

An aircraft is inspected where it is most at risk: the governing location has the highest
P(critical within the horizon), ties broken by the earliest inspect-by (none last), then by
name.  The summary lists every location with an active version of its own (app.services.models),
governing first; an aircraft whose only location is the default one has no summary, so its
answers stay exactly as before locations.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import date, datetime
from typing import Any

from sqlalchemy.orm import Session

from app.config import Settings
from app.default_location import DEFAULT_LOCATION
from app.services import aircraft_locations
from app.services import forecast as forecast_service
from app.services import locations as location_service
from app.services import models as model_service
from app.services.tail_status import below_critical


@dataclass(frozen=True)
class LocationSummary:
    """One location's forecast of a tail, in the fields a decision reads."""

    location: str
    model_version: int
    crack_as_of_m: float | None  # p50 on the as-of date; None at or past critical
    critical_crack_m: float
    prob_critical: float
    inspect_by: datetime | None
    overdue: bool
    past_critical: bool
    row_stamp: int | None = None  # the cached row it came from (None: not a function of one)


def governing_key(summary: LocationSummary) -> tuple[Any, ...]:
    """Most governing first: highest P(critical), earliest inspect-by (none last), name."""
    by = summary.inspect_by
    return (-summary.prob_critical, by is None, by or datetime.max, summary.location)


def summarise(
    session: Session,
    tail: str,
    *,
    horizon_days: int,
    as_of: date,
    settings: Settings,
    default: forecast_service.TailForecast | None = None,
) -> list[LocationSummary] | None:
    """The tail's locations with an active version, governing first; None where the default
    location is the only one (nothing to summarise).  default: the default location's forecast
    for the same horizon and as-of date where the caller has it (not made again); the others'
    decisions are read without their trajectories.  Raises NotFoundError, ConflictError (a
    location's forecast could not be made: no flights)."""
    listed = _listed(session, tail)
    if listed is None:
        return None
    out = []
    for name in listed:
        result = (
            default
            if default is not None and name == DEFAULT_LOCATION
            else forecast_service.forecast_tail(
                session,
                tail,
                horizon_days=horizon_days,
                settings=settings,
                as_of=as_of,
                location=name,
                trajectory=False,
            )
        )
        critical = result.critical_crack_m
        out.append(
            LocationSummary(
                location=name,
                model_version=result.model_version,
                crack_as_of_m=below_critical(result.crack_as_of.p50, critical),
                critical_crack_m=critical,
                prob_critical=result.risk.prob_critical,
                inspect_by=result.inspect_by,
                overdue=result.overdue,
                past_critical=result.past.past_critical,
                row_stamp=result.stamp,
            )
        )
    return sorted(out, key=governing_key)


def _listed(session: Session, tail: str) -> list[str] | None:
    """The names of the locations the tail carries that have an active version, sorted; None
    where the default location's is the only active version (nothing to summarise)."""
    active = model_service.active_versions(session)
    if len(active) < 2:
        return None
    carried = set(aircraft_locations.carried(session, tail))
    names = location_service.names_of(session, list(active)).values()
    return sorted(name for name in names if name in carried)


def current_stamps(session: Session, tail: str) -> tuple[tuple[str, int, int], ...] | None:
    """(location, active version, its row's stamp) of each location `summarise` would list,
    by name: what the aircraft's answer is a function of (with the settings, the horizon and
    the as-of date); None where a location's row is missing or there is nothing to summarise."""
    listed = _listed(session, tail)
    if listed is None:
        return None
    out = []
    for name in listed:
        stamp = forecast_service.current_stamp(session, tail, name)
        if stamp is None:
            return None
        out.append((name, *stamp))
    return tuple(out)


def stamps_of(summary: list[LocationSummary]) -> tuple[tuple[str, int, int], ...] | None:
    """current_stamps as the summary's own rows had them; None where a line had no row."""
    out = []
    for line in sorted(summary, key=lambda s: s.location):
        if line.row_stamp is None:
            return None
        out.append((line.location, line.model_version, line.row_stamp))
    return tuple(out)
