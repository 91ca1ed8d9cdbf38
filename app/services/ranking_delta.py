"""A version's kept fleet order brought up to date by re-reading only the rows that changed.

An ingest writes its tail's row at every location, which changes each version's fingerprint
(app.services.ranking_rows), so each API process made its next ranking anew: every location's
300 rows read, their risk decoded and sorted (~20 ms a location, ~90 ms a four-location
ranking; at one ingest a second, the rankings queued behind it).  A row's stamp changes with
every write of its state (app.tables), so the rows whose stamp is the one in the kept order are
the rows it was made from: only the others are read again, and the order is sorted anew.  The
order is a sort by a key unique per row (its tail last: app.services.ranking.urgency_key) of
every valid row with its risk, so the merged order is the one made from scratch.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from sqlalchemy.orm import Session

from app.config import Settings
from app.services import ranking_rows
from app.services.ranking_rows import CachedTail
from app.services.risk import Risk

Ranked = tuple[tuple[CachedTail, Risk], ...]
# above this share of a version's rows changed (and this many), one read of them all is cheaper
_MOST_CHANGED = 0.25
_FEW = 8


def changes(
    session: Session, version: int, settings: Settings, kept: Ranked
) -> tuple[list[CachedTail], set[int]] | None:
    """The rows of `version` whose stamp is not the kept order's (read again, valid ones) and
    the aircraft whose row is gone; None where the order must be made anew: a row without a
    stamp, a changed row not valid (another sample count), or too many changed."""
    now = ranking_rows.stamps(session, version)
    before = {row.aircraft_id: row.stamp for row, _ in kept}
    if any(stamp is None for stamp in now.values()):
        return None
    changed = [
        aircraft_id for aircraft_id, stamp in now.items() if before.get(aircraft_id) != stamp
    ]
    if len(changed) > max(_FEW, _MOST_CHANGED * len(now)):
        return None
    fresh = (
        ranking_rows.cached_tails(session, version, settings, states=False, aircraft_ids=changed)
        if changed
        else []
    )
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
