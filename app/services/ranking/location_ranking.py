"""The fleet's (tail, location) rows, grouped by aircraft: what the ranking and the export list
once several locations have models of their own.

Each location's rows are ordered as ever (app.services.ranking.order.ordered, per its active
version, batch-invariant: a row is its forecast's).  An aircraft's rows stay together, its
governing row first (as the aircraft's answer names it: `_governing`); aircraft are ordered
by their governing rows' urgency_key.  A fleet whose only active location is the default one
ranks as before (ranking.ranking, rows without a location); one whose only active location is
another names it on every row, so that an airline's own control point is not read as the whole
aircraft.
"""

from __future__ import annotations

from dataclasses import replace
from datetime import date
from typing import Any

from sqlalchemy.orm import Session

from app.config import Settings
from app.services import models as model_service
from app.services.forecasts.risk import Risk
from app.services.ranking import order as ranking_service
from app.services.ranking.order import urgency_key
from app.services.ranking.ranking_page import PageRow, RankedTail, ranked_rows
from app.services.ranking.ranking_rows import CachedTail
from app.services.records import locations
from app.tables import DEFAULT_LOCATION_ID


def ranking(
    session: Session,
    *,
    limit: int,
    settings: Settings,
    horizon_days: int,
    by: str = "risk",
    as_of: date | None = None,
    version: int | None = None,
    known: ranking_service.Known = None,
) -> tuple[int, float, int, list[RankedTail]]:
    """ranking.ranking's answer; with no version asked and several locations active, the
    (tail, location) rows grouped by aircraft, governing row first, each row naming its
    location, version and critical crack (the first two fields: the default location's).
    known: the active versions' fingerprints the caller read first (ranking.ordered's).
    Raises ValueError (unknown `by`), ConflictError (no active model), NotFoundError."""
    active = model_service.active_versions(session)
    if version is None and len(active) == 1:  # the one location with a model, default or not
        version = next(iter(active.values()))
    if version is not None or len(active) < 2:
        one = ranking_service.ranking(
            session,
            limit=limit,
            settings=settings,
            horizon_days=horizon_days,
            by=by,
            as_of=as_of,
            version=version,
            known=known,
        )
        return _named(session, *one)
    if by not in ranking_service.RANKINGS:
        raise ValueError(f"by must be one of {ranking_service.RANKINGS}, got {by!r}")
    as_of = as_of or settings.today()
    names = locations.names_of(session, list(active))
    rows: list[tuple[tuple[Any, ...], int, CachedTail, Risk]] = []
    for location_id, version_of in sorted(active.items()):
        ordered = ranking_service.ordered(
            session, version_of, settings, horizon_days, by, as_of, known=known
        )
        for cached, risk in ordered:
            key = (*urgency_key(by, cached.tail, risk)[:-1], names[location_id])
            rows.append((key, location_id, cached, risk))
    by_tail: dict[str, list[tuple[tuple[Any, ...], int, CachedTail, Risk]]] = {}
    for row in rows:
        by_tail.setdefault(row[2].tail, []).append(row)
    groups = [
        sorted(group, key=lambda r: _governing(r[3], names[r[1]])) for group in by_tail.values()
    ]
    groups.sort(key=lambda group: (group[0][0][:-1], group[0][2].tail, group[0][0][-1]))
    page = [row for group in groups for row in group][:limit]
    items = _items(session, page, active, names, settings, as_of)
    # the answer's own version and critical crack: the default location's (any, without one)
    default_version = active.get(DEFAULT_LOCATION_ID, active[min(active)])
    critical = ranking_service.critical_crack(session, default_version)
    return default_version, critical, len(rows), items


def _named(
    session: Session, version: int, critical: float, total: int, items: list[RankedTail]
) -> tuple[int, float, int, list[RankedTail]]:
    """A one-location answer as it is where its location is the default one; else each row
    names its location, version and critical crack, as (tail, location) rows do."""
    location_id = model_service.location_of(session, version)
    if location_id == DEFAULT_LOCATION_ID:
        return version, critical, total, items
    name = locations.names_of(session, [location_id])[location_id]
    named = [
        replace(item, location=name, model_version=version, critical_crack_m=critical)
        for item in items
    ]
    return version, critical, total, named


def _governing(risk: Risk, name: str) -> tuple[Any, ...]:
    """An aircraft's rows, governing first, as its answer names the governing location
    (app.services.forecasts.aircraft_summary.governing_key): highest P(critical), then the earliest
    inspect-by (none last; in flights, which one tail's rows share), then by name."""
    due = risk.inspect_by_flights
    return (-risk.prob_critical, due is None, 0 if due is None else due, name)


def _items(
    session: Session,
    page: list[tuple[tuple[Any, ...], int, CachedTail, Risk]],
    active: dict[int, int],
    names: dict[int, str],
    settings: Settings,
    as_of: date,
) -> list[RankedTail]:
    """The page's rows as RankedTail, in page order, each from its own location (its reads
    made once for the page: app.services.ranking.ranking_page)."""
    critical = {
        location_id: ranking_service.critical_crack(session, active[location_id])
        for location_id in sorted({row[1] for row in page})
    }
    rows = [PageRow(cached, risk, loc, critical[loc]) for _, loc, cached, risk in page]
    return [
        replace(
            item,
            location=names[row.location_id],
            model_version=active[row.location_id],
            critical_crack_m=row.critical,
        )
        for row, item in zip(rows, ranked_rows(session, rows, settings, as_of), strict=True)
    ]
