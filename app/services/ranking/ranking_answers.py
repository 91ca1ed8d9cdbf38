"""GET /fleet/ranking's answers, kept per process under the fingerprints of the rows they rank.

A ranking is a function of every active version's cached rows (the order, app.services.
ranking.order), of the inspections and repairs its page reads (every one of them drops its
subject's row: app.services.forecasts.forecast_cache.recorded), the active versions, the settings and
the request's parameters.  So each process keeps the encoded answer under each active
version's rows' fingerprint (app.services.ranking.ranking_rows.fingerprints: one aggregate each) and
serves it while they are the same: with four locations a kept order still cost ~12 ms a
ranking (each location's page read its inspections, repairs and flights, and 1,200 rows were
grouped by aircraft) against ~1 ms now.  An ingest changes its tail's rows, so the next
ranking in each process is made anew, by one request thread: the rankings that arrive
meanwhile wait for its answer (each making it too, ~25 ms of CPU apiece with four locations,
multiplied a change's CPU by the request threads when the load benchmark's rankings met).
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import date

from sqlalchemy.orm import Session

from app.config import Settings
from app.services.forecasts import forecast_cache
from app.services.memo import StampedMemo
from app.services.ranking import location_ranking, ranking_rows
from app.services.ranking.order import RankedTail

Answer = tuple[int, float, int, list[RankedTail]]
_ANSWERS: StampedMemo[bytes] = StampedMemo(64)
_STRIPES = 16


def encoded_ranking(
    session: Session,
    *,
    limit: int,
    settings: Settings,
    horizon_days: int,
    by: str,
    as_of: date,
    encode: Callable[[Answer], bytes],
) -> bytes:
    """app.services.ranking.location_ranking.ranking's answer as `encode` writes it, from the memo
    while no ranked row changed.  Raises ValueError (unknown `by`), ConflictError (no active
    model)."""
    current = _fingerprints(session)
    key = (str(session.get_bind().engine.url), limit, by, horizon_days, as_of)
    body = None if current is None else _ANSWERS.get(key, (current, settings))
    if body is not None:
        return body
    # a lock per answer asked, in _STRIPES stripes: one per parameter would grow without bound,
    # and one for all would make a ranking wait for another's sampling of a new day (~13 s)
    stripe = hash(key) % _STRIPES
    with forecast_cache.one_at_a_time(session, f"ranking answer {stripe}", 0):
        session.rollback()  # a fresh snapshot: the answer the previous thread kept counts
        current = _fingerprints(session)
        body = None if current is None else _ANSWERS.get(key, (current, settings))
        if body is not None:
            return body
        # read before the rows: the orders need not read them again
        known = None if current is None else {version: found for version, _, found in current}
        ranked = location_ranking.ranking(
            session,
            limit=limit,
            settings=settings,
            horizon_days=horizon_days,
            by=by,
            as_of=as_of,
            known=known,
        )
        body = encode(ranked)
        if current is not None:  # read before the rows: the answer is at least as new
            _ANSWERS.put(key, (current, settings), body)
    return body


def _fingerprints(
    session: Session,
) -> tuple[tuple[int, int, ranking_rows.Fingerprint], ...] | None:
    """(active version, its location, its rows' fingerprint) of every active version, in one
    query; None where a version has a row without a stamp or a tail with flights and no row (a
    ranking fills it first)."""
    out = []
    for version, (location_id, found) in sorted(ranking_rows.fingerprints(session).items()):
        if found is None or found[1] > 0:
            return None
        out.append((version, location_id, found))
    return tuple(out)
