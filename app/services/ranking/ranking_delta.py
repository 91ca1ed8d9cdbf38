"""A version's kept fleet order brought up to date by re-reading only the rows that changed.

An ingest writes its tail's row at every location, which changes each version's fingerprint
(app.services.ranking.ranking_rows), so each API process made its next ranking anew: every location's
300 rows read, their risk decoded and sorted (~20 ms a location, ~90 ms a four-location
ranking; at one ingest a second, the rankings queued behind it).  A row's stamp changes with
every write of its state (app.tables), so the rows whose stamp is the one in the kept order are
the rows it was made from: only the others are read again, and the order is sorted anew.  The
order is a sort by a key unique per row (its tail last: app.services.ranking.order.urgency_key) of
every valid row with its risk, so the merged order is the one made from scratch.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from datetime import date
from typing import Any

from sqlalchemy.orm import Session

from app.config import Settings
from app.in_lists import chunks
from app.services import models as model_service
from app.services.forecasts import cache_rows
from app.services.forecasts.risk import Risk, cached_risk, check_sampled, fill_risk
from app.services.ranking import ranking_rows
from app.services.ranking.ranking_rows import CachedTail

Ranked = tuple[tuple[CachedTail, Risk], ...]
# above this share of a version's rows changed (and this many), one read of them all is cheaper
_MOST_CHANGED = 0.25
_FEW = 8


def changes(
    session: Session, version: int, settings: Settings, kept: Ranked, *, bounded: bool = True
) -> tuple[list[CachedTail], set[int]] | None:
    """The rows of `version` whose stamp is not the kept order's (read again, valid ones) and
    the aircraft whose row is gone; None where the order must be made anew: a row without a
    stamp, a changed row not valid (another sample count), or (where `bounded`) too many
    changed."""
    now = ranking_rows.stamps(session, version)
    before = {row.aircraft_id: row.stamp for row, _ in kept}
    if any(stamp is None for stamp in now.values()):
        return None
    changed = [
        aircraft_id for aircraft_id, stamp in now.items() if before.get(aircraft_id) != stamp
    ]
    if bounded and len(changed) > max(_FEW, _MOST_CHANGED * len(now)):
        return None
    fresh = [
        row
        for part in chunks(changed)
        for row in ranking_rows.cached_tails(
            session, version, settings, states=False, aircraft_ids=part
        )
    ]
    if len(fresh) != len(changed) or any(row.stamp is None for row in fresh):
        return None
    return fresh, set(before) - set(now)


def merged(
    kept: Ranked,
    fresh: list[tuple[CachedTail, Risk]],
    gone: set[int],
    key: Callable[[tuple[CachedTail, Risk]], Any],
) -> Ranked:
    """The kept order without the gone and changed rows, with the changed ones as read again,
    sorted by `key`."""
    dropped = gone | {row.aircraft_id for row, _ in fresh}
    rows = [item for item in kept if item[0].aircraft_id not in dropped]
    return tuple(sorted([*rows, *fresh], key=key))


def reordered(
    session: Session,
    version: int,
    settings: Settings,
    horizon_days: int,
    as_of: date,
    kept: Ranked,
    key: Callable[[tuple[CachedTail, Risk]], Any],
    *,
    bounded: bool = True,
) -> Ranked | None:
    """The kept order with the rows changed since re-read (changes), sorted by `key`; their
    risk over horizon_days after as_of sampled and stored where missing (an ingest stores
    today's alone: the worker's order of tomorrow samples only the tails ingested).  None
    where the order must be made anew."""
    found = changes(session, version, settings, kept, bounded=bounded)
    if found is None:
        return None
    fresh, gone = found
    risks = [cached_risk(row, horizon_days, settings, as_of) for row in fresh]
    missing = [row.aircraft_id for row, risk in zip(fresh, risks, strict=True) if risk is None]
    if missing:
        states = [
            row
            for part in chunks(missing)
            for row in ranking_rows.cached_tails(
                session, version, settings, states=True, aircraft_ids=part
            )
        ]
        read = {row.aircraft_id: row.stamp for row in fresh}
        if any(row.state is None or read[row.aircraft_id] != row.stamp for row in states):
            return None  # changed again since: made anew
        sampled = [row.state for row in states if row.state is not None]
        check_sampled(sampled, horizon_days, settings, as_of)
        posterior = model_service.load_posterior(session, version)
        fill_risk(posterior, sampled, horizon_days, settings, bands=False, as_of=as_of)
        cache_rows.store_risk(session, sampled, bands=False)  # keeps their stamps
        session.commit()
        risk_of = {state.aircraft_id: state.risk for state in sampled}
        fresh = [replace(row, risk=risk_of.get(row.aircraft_id, row.risk)) for row in fresh]
        risks = [cached_risk(row, horizon_days, settings, as_of) for row in fresh]
    if any(risk is None for risk in risks):
        return None
    rows = [(row, risk) for row, risk in zip(fresh, risks, strict=True) if risk is not None]
    return merged(kept, rows, gone, key)
