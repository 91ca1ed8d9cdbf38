"""A ranking's page as it is answered: each row with its dates and decisions, its last and
flagged inspections at its location, its tail's last flight and, where its location gives a
limit stress, the residual strength at its p50 crack today with its margin (computed where an
aircraft's line computes it: app.services.forecasts.residual_now.line_strength).

The page's reads are made once for all its rows, whatever their locations: three queries (a
fourth where a repair set a row's origin).  Per location, a four-location page made twelve,
about a third of the CPU of a ranking made anew after an ingest (benchmarks/RESULTS.md,
session 15), which each API process pays once per change while its rankings wait.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import date, datetime

from sqlalchemy import func, select, tuple_
from sqlalchemy.orm import Session

from app.config import Settings
from app.in_lists import IN_LIST, chunks
from app.services.forecasts.residual_now import LineStrength, line_strength
from app.services.forecasts.risk import Dates, Risk, decisions
from app.services.forecasts.tail_status import DataAge, PastCritical, data_age, last_flights_of
from app.services.ranking.ranking_rows import CachedTail
from app.services.records.locations import locations_by_id
from app.tables import Inspection


@dataclass(frozen=True)
class LastInspection:
    inspection_id: str
    inspected_at: datetime
    detected: bool
    crack_length_m: float | None
    repaired: bool


@dataclass(frozen=True)
class RankedTail:
    tail: str
    crack_length_m: float
    flights_to_critical: int | None
    critical_date: datetime | None
    flights_flown: int
    origin: datetime
    flights_per_day: float
    computed_at: datetime
    risk: Risk
    critical_dates: Dates
    inspect_by: datetime | None
    overdue: bool
    last_inspection: LastInspection | None
    data_age: DataAge
    past: PastCritical
    # inspections that disagreed strongly with the tail's forecast (app.services.forecasts.assessment)
    flagged_inspection_ids: tuple[str, ...] = ()
    # The row's location, version and critical crack where the fleet ranks (tail, location)
    # rows (app.services.ranking.location_ranking); None in a one-location ranking.
    location: str | None = None
    model_version: int | None = None
    critical_crack_m: float | None = None
    # at the p50 crack on the as-of date, where the row's location gives a limit stress
    residual_strength: LineStrength | None = None


@dataclass(frozen=True)
class PageRow:
    """A ranked row of the page: its cached row and risk, its location and that location's
    critical crack."""

    cached: CachedTail
    risk: Risk
    location_id: int
    critical: float


Subject = tuple[int, int]  # (aircraft id, location id)
_PAIR = tuple_(Inspection.aircraft_id, Inspection.location_id)


def last_inspections(
    session: Session, subjects: Sequence[Subject]
) -> dict[Subject, LastInspection]:
    """Each subject's latest inspection at its location (of those at the same time, the last
    by inspection id)."""
    out: dict[Subject, LastInspection] = {}
    for part in chunks(sorted(set(subjects)), IN_LIST // 2):  # two values a subject
        latest = (
            select(
                Inspection.aircraft_id,
                Inspection.location_id,
                func.max(Inspection.inspected_at).label("at"),
            )
            .where(_PAIR.in_(part))
            .group_by(Inspection.aircraft_id, Inspection.location_id)
            .subquery()
        )
        query = (
            select(Inspection)
            .join(
                latest,
                (Inspection.aircraft_id == latest.c.aircraft_id)
                & (Inspection.location_id == latest.c.location_id)
                & (Inspection.inspected_at == latest.c.at),
            )
            .order_by(Inspection.inspection_id)
        )
        for i in session.scalars(query):
            out[(i.aircraft_id, i.location_id)] = LastInspection(
                i.inspection_id, i.inspected_at, i.detected, i.crack_length_m, i.repaired
            )
    return out


def flagged_inspections(
    session: Session, subjects: Sequence[Subject]
) -> dict[Subject, tuple[str, ...]]:
    """Each subject's flagged inspections at its location, oldest first."""
    out: dict[Subject, tuple[str, ...]] = {}
    for part in chunks(sorted(set(subjects)), IN_LIST // 2):
        query = (
            select(Inspection.aircraft_id, Inspection.location_id, Inspection.inspection_id)
            .where(_PAIR.in_(part), Inspection.flagged)
            .order_by(Inspection.inspected_at, Inspection.inspection_id)
        )
        for aircraft_id, location_id, inspection_id in session.execute(query):
            key = (aircraft_id, location_id)
            out[key] = (*out.get(key, ()), inspection_id)
    return out


def ranked_rows(
    session: Session, page: Sequence[PageRow], settings: Settings, as_of: date
) -> list[RankedTail]:
    """The page's rows as RankedTail, in page order: dates, overdue, each row's last and
    flagged inspections at its location, data age, past critical and residual strength."""
    subjects = [(row.cached.aircraft_id, row.location_id) for row in page]
    entries = locations_by_id(session, [row.location_id for row in page])
    inspections = last_inspections(session, subjects)
    flagged = flagged_inspections(session, subjects)
    flown = last_flights_of(session, [(row.cached.aircraft_id, row.cached.origin) for row in page])
    items = []
    for row, subject, last_flown in zip(page, subjects, flown, strict=True):
        f, risk = row.cached, row.risk
        decided = decisions(f.origin, risk, f.flights_per_day, row.critical, as_of)
        last = inspections.get(subject)
        items.append(
            RankedTail(
                tail=f.tail,
                crack_length_m=f.crack_length_m,
                flights_to_critical=f.flights_to_critical,
                critical_date=f.critical_date,
                flights_flown=f.flights_flown,
                origin=f.origin,
                flights_per_day=f.flights_per_day,
                computed_at=f.computed_at,
                risk=risk,
                critical_dates=decided.critical_dates,
                inspect_by=decided.inspect_by,
                overdue=decided.overdue,
                last_inspection=last,
                data_age=data_age(
                    last_flown,
                    None if last is None else last.inspected_at,
                    as_of,
                    stale_after_days=settings.stale_after_days,
                ),
                past=decided.past,
                flagged_inspection_ids=flagged.get(subject, ()),
                residual_strength=line_strength(
                    entries[row.location_id], risk.crack_as_of[1], settings
                ),
            )
        )
    return items
