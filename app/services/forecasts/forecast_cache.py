"""The forecast cache (table forecasts): where each tail stands under one model version.

A row holds, per tail and version, the crack after the last recorded flight (marched from the
tail's last repair), the same crack under every posterior draw (crack_samples_m: one compiled
march of the history per sample over a batch of tails, done when the row is filled), the tail's
utilization, its time to critical, and the sampled risk and daily bands per horizon
(app.services.forecasts.risk).  Marching a 7,300-flight history per request instead would cost samples x
3.4 ms, about 0.7 s at 200 samples.

Its rows are read and written by app.services.forecasts.cache_rows alone.  One validity rule
(cache_rows.valid_row): a row of the version with forecast_samples crack samples.  A
committed row is never behind its tail's flights: the ingest that stores new flights advances
its tails' rows in its own transaction (recorded: app.services.forecasts.cache_advance marches 1-4 flights
instead of the history under every draw), and whatever else changes a tail's history (a
corrected or deleted record, a new inspection, a repair, a new initial crack) drops its rows
through invalidate().  So readers only read rows; a missing one is filled by fill_missing, one
filler per database and version in a process (one_at_a_time), so concurrent requests wait for it
instead of marching the same histories again.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager

import pandas as pd
from sqlalchemy.orm import Session

from app.config import Settings
from app.errors import ConflictError
from app.services import models as model_service
from app.services.forecasts import cache_advance, cache_fill, cache_rows
from app.services.forecasts.cache_rows import CacheState, Subject

_fillers: dict[tuple[str, str, int], threading.Lock] = {}
_fillers_guard = threading.Lock()


@contextmanager
def one_at_a_time(session: Session, what: str, version: int) -> Iterator[None]:
    """Hold the lock of `what` (e.g. "rows", "risk") for this database and version in this
    process: concurrent requests wait for the one filler instead of filling the same rows."""
    key = (str(session.get_bind().engine.url), what, version)
    with _fillers_guard:
        lock = _fillers.setdefault(key, threading.Lock())
    with lock:
        yield


def invalidate(session: Session, aircraft_ids: Sequence[int]) -> None:
    """Drop the cached rows of these aircraft under every version (caller commits)."""
    cache_rows.drop(session, aircraft_ids)


def recorded(
    session: Session, noun: str, records: pd.DataFrame, time: str, settings: Settings
) -> None:
    """New records (columns aircraft_id and `time`) were stored; bring the cache up to them in
    the same transaction (the caller commits).  Flights after a row's origin advance the rows of
    the active version and of newer ones (a retrain's being filled) over them
    (cache_advance.catch_up); rows of older versions, rows whose origin lies at or after a new
    flight, and every row of a tail with a new inspection at its location (it moves that
    location's growth posterior; the tail's other locations keep theirs) are dropped, for their
    next reader to recompute."""
    if noun != "flights":
        if "location_id" not in records.columns:
            invalidate(session, records["aircraft_id"].tolist())
            return
        pairs = records[["aircraft_id", "location_id"]].drop_duplicates()
        subjects = [Subject(int(a), int(loc)) for a, loc in pairs.itertuples(index=False)]
        cache_rows.drop_subjects(session, subjects)
        return
    active = model_service.active_versions(session)  # each location's
    earliest = records.groupby("aircraft_id")[time].min()
    for aircraft_id, flown_at in zip(earliest.index.tolist(), earliest, strict=True):
        cache_rows.drop_outdated(session, aircraft_id, flown_at.to_pydatetime())
    rows = cache_rows.locked(session, earliest.index.tolist())
    older = [r for r in rows if r.model_version < active.get(r.location_id, r.model_version)]
    cache_rows.drop_states(session, older)
    cache_advance.catch_up(session, [r for r in rows if r not in older], settings)


def fill_missing(
    session: Session, version: int, settings: Settings, aircraft_ids: Sequence[int] | None = None
) -> None:
    """Fill the missing rows of `version` (of aircraft_ids, default all).  One filler at a time
    per database and version in this process; what another filler stored meanwhile is kept."""
    if not cache_rows.missing(session, version, settings, aircraft_ids):
        return
    with one_at_a_time(session, "rows", version):
        session.rollback()  # a fresh snapshot: rows the previous filler committed count
        todo = cache_rows.missing(session, version, settings, aircraft_ids)
        if todo:
            refresh(session, version, settings, aircraft_ids=todo)


def cached_state(
    session: Session, subject: Subject, version: int, settings: Settings, *, bands: bool = True
) -> CacheState:
    """A snapshot of the subject's valid row (its bands unread without `bands`), filled first
    where missing (an ingest advancing or dropping the row meanwhile cannot change it under
    the caller).  Raises ConflictError (no flights)."""
    state = cache_rows.valid_state(session, subject, version, settings, bands=bands)
    if state is None:
        fill_missing(session, version, settings, aircraft_ids=[subject.aircraft_id])
        session.expire_all()
        state = cache_rows.valid_state(session, subject, version, settings, bands=bands)
    if state is None:
        raise ConflictError("the tail has no recorded flights: a forecast starts at the last one")
    return state


def refresh(
    session: Session,
    version: int,
    settings: Settings,
    *,
    aircraft_ids: Sequence[int] | None = None,
    progress: Callable[[float], None] | None = None,
    known: cache_fill.Known | None = None,
    ahead: bool = True,
) -> int:
    """Recompute the cached rows of these aircraft (default: all with flights) under `version`
    (app.services.forecasts.cache_fill; `known`: a history the caller already read; `ahead`: tomorrow's
    risk too).  Returns the number of tails stored."""
    return cache_fill.fill(
        session,
        version,
        settings,
        aircraft_ids=aircraft_ids,
        progress=progress,
        known=known,
        ahead=ahead,
    )
