"""The fleet's (tail, location) rows, grouped by aircraft: what the ranking and the export list
once several locations have models of their own.

Each location's rows are ordered as ever (app.services.ranking.ordered, per its active
version, batch-invariant: a row is its forecast's).  An aircraft's rows stay together, its
governing row first (the most urgent of its locations by the ranking's urgency_key); aircraft
are ordered by their governing rows.  A fleet whose only active location is the default one
ranks as before (ranking.ranking, rows without a location).
"""

from __future__ import annotations

from dataclasses import replace
from datetime import date
from typing import Any

from sqlalchemy.orm import Session

from app.config import Settings
from app.services import locations
from app.services import models as model_service
from app.services import ranking as ranking_service
from app.services.ranking import RankedTail, urgency_key
from app.services.ranking_rows import CachedTail
from app.services.risk import Risk
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
) -> tuple[int, float, int, list[RankedTail]]:
    """ranking.ranking's answer; with no version asked and several locations active, the
    (tail, location) rows grouped by aircraft, governing row first, each row naming its
    location, version and critical crack (the first two fields: the default location's).
    Raises ValueError (unknown `by`), ConflictError (no active model), NotFoundError."""
    active = model_service.active_versions(session)
    if version is not None or len(active) < 2:
        return ranking_service.ranking(
            session,
            limit=limit,
            settings=settings,
            horizon_days=horizon_days,
            by=by,
            as_of=as_of,
            version=version,
        )
    if by not in ranking_service.RANKINGS:
        raise ValueError(f"by must be one of {ranking_service.RANKINGS}, got {by!r}")
    as_of = as_of or settings.today()
    names = locations.names_of(session, list(active))
    rows: list[tuple[tuple[Any, ...], int, CachedTail, Risk]] = []
    for location_id, version_of in sorted(active.items()):
        ordered = ranking_service.ordered(session, version_of, settings, horizon_days, by, as_of)
        for cached, risk in ordered:
            key = (*urgency_key(by, cached.tail, risk)[:-1], names[location_id])
            rows.append((key, location_id, cached, risk))
    by_tail: dict[str, list[tuple[tuple[Any, ...], int, CachedTail, Risk]]] = {}
    for row in rows:
        by_tail.setdefault(row[2].tail, []).append(row)
    groups = [sorted(group, key=lambda r: r[0]) for group in by_tail.values()]
    groups.sort(key=lambda group: (group[0][0][:-1], group[0][2].tail, group[0][0][-1]))
    page = [row for group in groups for row in group][:limit]
    items = _items(session, page, active, names, settings, as_of)
    # the answer's own version and critical crack: the default location's (any, without one)
    default_version = active.get(DEFAULT_LOCATION_ID, active[min(active)])
    critical = ranking_service.critical_crack(session, default_version)
    return default_version, critical, len(rows), items


def _items(
    session: Session,
    page: list[tuple[tuple[Any, ...], int, CachedTail, Risk]],
    active: dict[int, int],
    names: dict[int, str],
    settings: Settings,
    as_of: date,
) -> list[RankedTail]:
    """The page's rows as RankedTail, in page order, each from its own location."""
    out: list[RankedTail | None] = [None] * len(page)
    for location_id, version in active.items():
        mine = [k for k, row in enumerate(page) if row[1] == location_id]
        if not mine:
            continue
        critical = ranking_service.critical_crack(session, version)
        built = ranking_service.ranked_items(
            session,
            [(page[k][2], page[k][3]) for k in mine],
            settings,
            as_of,
            critical,
            location_id,
        )
        for k, item in zip(mine, built, strict=True):
            out[k] = replace(
                item, location=names[location_id], model_version=version, critical_crack_m=critical
            )
    assert all(item is not None for item in out)
    return [item for item in out if item is not None]
