"""The fleet in order: the ranking (GET /fleet/ranking), also the order of the export
(app.services.ranking.export).

Both order tails with urgency_key.  "Most urgent" (by="risk", the ranking's default and the
export's order): the highest P(critical within the horizon), then the largest p95 crack now.
Horizons count from the as-of date (app.services.forecasts.risk).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from datetime import date
from typing import Any

from sqlalchemy import Select, exists, select
from sqlalchemy.orm import Session

from app import budget
from app.config import Settings
from app.services import models as model_service
from app.services.forecasts import cache_rows, forecast_cache
from app.services.forecasts.risk import Risk, cached_risk, check_sampled, fill_risk
from app.services.memo import StampedMemo
from app.services.ranking import ranking_delta, ranking_rows
from app.services.ranking.ranking_page import PageRow, RankedTail, ranked_rows
from app.services.ranking.ranking_rows import CachedTail
from app.services.records.carriage import carries
from app.tables import DEFAULT_LOCATION_ID, Aircraft, Flight, ModelVersion

RANKINGS = ("risk", "crack", "due")
_has_flights = Flight.aircraft_id == Aircraft.id


def _subjects(version: int) -> Select[int]:
    """The aircraft a version's ranking lists: with flights, carrying its location."""
    location = select(ModelVersion.location_id).where(ModelVersion.version == version)
    return select(Aircraft.id).where(
        exists().where(_has_flights), carries(location.scalar_subquery())
    )


# times a ranking fills rows that writes dropped while it read (each fill brings them back)
_REFILLS = 3


def urgency_key(by: str, tail: str, risk: Risk) -> tuple[Any, ...]:
    """Sort key, most urgent first: by risk (P(critical), then p95 crack now), crack (p50 crack
    now, largest first) or due (earliest inspect-by; none due last, then by risk); ties by tail.
    Raises ValueError for an unknown `by`."""
    if by not in RANKINGS:
        raise ValueError(f"by must be one of {RANKINGS}, got {by!r}")
    p95 = risk.crack_now[2] if risk.crack_now[2] is not None else float("inf")
    p50 = risk.crack_now[1] if risk.crack_now[1] is not None else float("inf")
    if by == "risk":
        return (-risk.prob_critical, -p95, tail)
    if by == "crack":
        return (-p50, tail)
    due = risk.inspect_by_flights
    return (due is None, 0 if due is None else due, -risk.prob_critical, -p95, tail)


def _complete_rows(
    session: Session, version: int, settings: Settings, *, states: bool = False
) -> list[CachedTail]:
    """_valid_rows with every tail that has flights: rows a write dropped since the caller
    filled them are filled again (up to _REFILLS times)."""
    rows = ranking_rows.cached_tails(session, version, settings, states=states)
    for _ in range(_REFILLS):
        flown = set(session.scalars(_subjects(version)))
        if flown <= {row.aircraft_id for row in rows}:
            break
        forecast_cache.fill_missing(session, version, settings)
        rows = ranking_rows.cached_tails(session, version, settings, states=states)
    return rows


# Fingerprints by version read by the caller before any row (ordered's `known`)
Known = Mapping[int, ranking_rows.Fingerprint] | None

# The fleet in order per (database, version, horizon, by, as-of date), kept under the
# fingerprint of the rows it was read from (app.services.ranking.ranking_rows.fingerprints): a ranking
# whose rows are all unchanged, with every tail that has flights among them, reuses it instead
# of reading and decoding 300 rows' risk (~9 ms of a ranking's 11).
Ranked = tuple[tuple[CachedTail, Risk], ...]
_ORDERED: StampedMemo[Ranked] = StampedMemo(32)


def ordered(
    session: Session,
    version: int,
    settings: Settings,
    horizon_days: int,
    by: str,
    as_of: date,
    *,
    known: Known = None,
) -> Ranked:
    """The valid cached rows of `version` with their risk over horizon_days after as_of, most
    urgent first: every tail with flights once, rows dropped by a write meanwhile filled again
    (up to _REFILLS times).

    The default horizon's risk is stored ahead as of today and tomorrow (fills, the worker:
    risk.days_ahead, app.worker), so a ranking normally only reads rows.  Risk not cached yet
    (another horizon or as-of date) is sampled by one filler per version and process (300
    tails x 200 samples, ~13 s); concurrent rankings wait for it and then answer from what it
    stored, so every ranking is complete and as of the date asked (a ranking from an earlier
    day's risk would mark the wrong tails overdue).  A row that changed while its risk was
    sampled is ranked on the state sampled, and its new state is sampled next time.  The order
    is kept per process under its rows' fingerprint (_ORDERED) while none of them changes, and
    once some do, brought up to date from those rows alone (app.services.ranking.ranking_delta).
    known: fingerprints by version that the caller read in this transaction before any row
    (app.services.ranking.ranking_answers), used instead of reading them again (two aggregates a
    version, twice where the order changed: ~1 ms of CPU each).
    """
    key = (str(session.get_bind().engine.url), version, horizon_days, by, as_of)
    given = None if known is None else known.get(version)
    current = given or _fingerprint(session, version)
    kept = None if current is None else _ORDERED.get(key, (current, settings))
    if kept is not None:
        return kept
    # One thread orders the fleet once its rows changed; the others wait for its order (each
    # ordering it too multiplied the CPU of a change by the request threads).
    with forecast_cache.one_at_a_time(session, f"order {horizon_days} {by} {as_of}", version):
        # read before the rows: an order kept under it is at least as new as what it names
        current = given or _fingerprint(session, version)
        kept = None if current is None else _ORDERED.get(key, (current, settings))
        if kept is not None:
            return kept
        last = _ORDERED.last(key)  # (fingerprint, settings) and the order kept under them
        ranked = None
        if current is not None and last is not None and last[0][1] == settings:  # type: ignore[index]
            ranked = ranking_delta.reordered(
                session, version, settings, horizon_days, as_of, last[1], _key(by)
            )
        read_only = ranked is not None
        if ranked is None:
            ranked, read_only = _order(session, version, settings, horizon_days, by, as_of)
        if read_only and current is not None:
            _ORDERED.put(key, (current, settings), ranked)
        return ranked


def _fingerprint(session: Session, version: int) -> ranking_rows.Fingerprint | None:
    """The version's rows' fingerprint (app.services.ranking.ranking_rows.fingerprints); None where a
    row has no stamp or a tail with flights has no row (a ranking must fill it first)."""
    _, found = ranking_rows.fingerprints(session, version).get(version, (None, None))
    return None if found is None or found[1] > 0 else found


def _order(
    session: Session, version: int, settings: Settings, horizon_days: int, by: str, as_of: date
) -> tuple[Ranked, bool]:
    """ordered() read and sorted from the rows, and whether it may be kept (False: it sampled
    risk, or read a row without a stamp; rows it filled changed the fingerprint read before,
    so an order kept under that one is never served)."""
    rows = _complete_rows(session, version, settings)
    risks = [cached_risk(row, horizon_days, settings, as_of) for row in rows]
    if any(risk is None for risk in risks):
        with forecast_cache.one_at_a_time(session, "risk", version):
            session.rollback()  # a fresh snapshot: what the previous filler stored counts
            rows = _complete_rows(session, version, settings, states=True)
            uncached = [
                row.state
                for row in rows
                if row.state is not None and cached_risk(row, horizon_days, settings, as_of) is None
            ]
            if uncached:
                check_sampled(uncached, horizon_days, settings, as_of)
                posterior = model_service.load_posterior(session, version)
                try:
                    fill_risk(posterior, uncached, horizon_days, settings, bands=False, as_of=as_of)
                except budget.DeadlineExceeded:
                    # out of time: keep what was sampled, so that the next ranking goes on
                    sampled = [
                        s
                        for s in uncached
                        if cached_risk(s, horizon_days, settings, as_of) is not None
                    ]
                    cache_rows.store_risk(session, sampled, bands=False)
                    session.commit()
                    raise
                cache_rows.store_risk(session, uncached, bands=False)
                session.commit()
            rows = [replace(row, risk=row.state.risk) if row.state else row for row in rows]
            risks = [cached_risk(row, horizon_days, settings, as_of) for row in rows]
        return _by_urgency(rows, risks, by), False
    return _by_urgency(rows, risks, by), not any(row.stamp is None for row in rows)


def _key(by: str) -> Callable[[tuple[CachedTail, Risk]], tuple[Any, ...]]:
    """urgency_key(by) of a (row, risk) pair."""
    return lambda item: urgency_key(by, item[0].tail, item[1])


def _by_urgency(rows: Sequence[CachedTail], risks: Sequence[Risk | None], by: str) -> Ranked:
    ranked = []
    for row, risk in zip(rows, risks, strict=True):
        assert risk is not None
        ranked.append((row, risk))
    return tuple(sorted(ranked, key=lambda item: urgency_key(by, item[0].tail, item[1])))


def ranking(
    session: Session,
    *,
    limit: int,
    settings: Settings,
    horizon_days: int,
    by: str = "risk",
    as_of: date | None = None,
    version: int | None = None,
    known: Known = None,
) -> tuple[int, float, int, list[RankedTail]]:
    """Tails of `version` (default: the active one) ordered by urgency_key(by) over
    horizon_days after as_of (default settings.today()); known: as ordered's.

    Fills the cache for tails whose row is missing (a new tail, a correction, an inspection)
    and the sampled risk of the horizon where not cached yet.  Returns (model version, critical crack, tails ranked in all,
    the first `limit`).  Raises ValueError for an unknown `by`, ConflictError (no active model),
    NotFoundError (unknown version).
    """
    if by not in RANKINGS:
        raise ValueError(f"by must be one of {RANKINGS}, got {by!r}")
    if version is None:
        version = model_service.require_active_version(session)
    else:
        model_service.get_version(session, version)
    as_of = as_of or settings.today()
    ranked = ordered(session, version, settings, horizon_days, by, as_of, known=known)
    critical = critical_crack(session, version)
    location_id = model_service.location_of(session, version)
    items = ranked_items(session, ranked[:limit], settings, as_of, critical, location_id)
    return version, critical, len(ranked), items


def critical_crack(session: Session, version: int) -> float:
    """The critical crack of a version's physics (its location's)."""
    return float(model_service.load_posterior(session, version).law.critical_crack_m)


def ranked_items(
    session: Session,
    page: Ranked | Sequence[tuple[CachedTail, Risk]],
    settings: Settings,
    as_of: date,
    critical: float,
    location_id: int = DEFAULT_LOCATION_ID,
) -> list[RankedTail]:
    """The page's rows of one location as RankedTail (app.services.ranking.ranking_page)."""
    rows = [PageRow(cached, risk, location_id, critical) for cached, risk in page]
    return ranked_rows(session, rows, settings, as_of)


def warm(session: Session, settings: Settings, as_of: date, *, fill: bool = True) -> int | None:
    """Fill every location's active version's missing rows and sample their risk over
    forecast_horizon_days after as_of where not stored yet (app.worker calls it for today and
    tomorrow while idle, so a ranking only reads rows).  Without `fill`, a version with rows
    missing is left to their readers (a fill stores tomorrow's risk too).  Returns the default
    location's active version (None: none)."""
    active = model_service.active_versions(session)
    horizon = min(settings.forecast_horizon_days, settings.max_horizon_days)
    for version in active.values():
        if fill:
            ordered(session, version, settings, horizon, "risk", as_of)
        else:
            _brought_up_to_date(session, version, settings, horizon, as_of)
    return active.get(DEFAULT_LOCATION_ID)


def _brought_up_to_date(
    session: Session, version: int, settings: Settings, horizon_days: int, as_of: date
) -> None:
    """ordered() by risk where the kept order can be brought up to date from its changed rows
    alone (ranking_delta.reordered, however many: a bulk upload's tails too); nothing where rows are
    missing or none is kept (their readers, or the next warm with fill, make it)."""
    key = (str(session.get_bind().engine.url), version, horizon_days, "risk", as_of)
    with forecast_cache.one_at_a_time(session, f"order {horizon_days} risk {as_of}", version):
        current = _fingerprint(session, version)
        last = _ORDERED.last(key)
        if current is None or last is None or last[0] == (current, settings):
            return
        if last[0][1] != settings:  # type: ignore[index]
            return
        ranked = ranking_delta.reordered(
            session, version, settings, horizon_days, as_of, last[1], _key("risk"), bounded=False
        )
        if ranked is not None:
            _ORDERED.put(key, (current, settings), ranked)
