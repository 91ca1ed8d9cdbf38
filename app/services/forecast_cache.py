"""The forecast cache (table forecasts): where each tail stands under one model version.

A row holds, per tail and version, the crack after the last recorded flight (marched from the
tail's last repair), the same crack under every posterior draw (crack_samples_m: one compiled
march of the history per sample over a batch of tails, done when the row is filled), the tail's
utilization, its time to critical, and the sampled risk and daily bands per horizon
(app.services.risk).  Marching a 7,300-flight history per request instead would cost samples x
3.4 ms, about 0.7 s at 200 samples.

One validity rule (valid_row): a row of the version with forecast_samples crack samples.  A
row is current when no flight lies after its origin; new flights leave it in place and the next
reader advances it over them (app.services.cache_advance: 1-4 flights instead of the history
under every draw).  One way out: invalidate(), called by whatever else changes a tail's history
(a corrected or deleted record, a new inspection, a repair, a new initial crack).  Requests fill
missing rows and advance rows behind through fill_missing: one filler per database and version
in a process (one_at_a_time), so concurrent requests wait for it instead of marching the same
histories again; rows are written guarded by what was read, so fillers of two processes never
advance a row twice.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager

import pandas as pd
from sqlalchemy import ColumnElement, and_, delete, exists, func, select
from sqlalchemy.orm import Session

from app.config import Settings
from app.errors import ConflictError
from app.services import cache_advance, cache_fill
from app.services import models as model_service
from app.storage import chunks
from app.tables import Aircraft, Flight, Forecast

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
    for part in chunks(sorted(set(aircraft_ids))):
        session.execute(delete(Forecast).where(Forecast.aircraft_id.in_(part)))


def recorded(session: Session, noun: str, records: pd.DataFrame, time: str) -> None:
    """New records (columns aircraft_id and `time`) were stored (caller commits).  Flights after
    a row's origin keep it: the next reader advances it over them (cache_advance).  A flight at
    or before the origin, or any inspection (it moves its tail's growth posterior), drops the
    tail's rows."""
    if noun != "flights":
        invalidate(session, records["aircraft_id"].tolist())
        return
    earliest = records.groupby("aircraft_id")[time].min()
    for aircraft_id, flown_at in zip(earliest.index.tolist(), earliest, strict=True):
        session.execute(
            delete(Forecast).where(
                Forecast.aircraft_id == aircraft_id,
                Forecast.origin >= flown_at.to_pydatetime(),
            )
        )


def valid_row(version: int, settings: Settings) -> ColumnElement[bool]:
    """Rows that serve `version` under these settings: filled with forecast_samples samples."""
    return and_(
        Forecast.model_version == version,
        func.length(Forecast.crack_samples_m) == 8 * settings.forecast_samples,
    )


def missing(
    session: Session, version: int, settings: Settings, aircraft_ids: Sequence[int] | None = None
) -> list[int]:
    """Aircraft with flights and no valid row of `version` (among aircraft_ids if given)."""
    cached = exists().where(Forecast.aircraft_id == Aircraft.id, valid_row(version, settings))
    query = select(Aircraft.id).where(exists().where(Flight.aircraft_id == Aircraft.id), ~cached)
    if aircraft_ids is None:
        return list(session.scalars(query))
    return [
        i
        for part in chunks(list(aircraft_ids))
        for i in session.scalars(query.where(Aircraft.id.in_(part)))
    ]


def behind(
    session: Session, version: int, settings: Settings, aircraft_ids: Sequence[int] | None = None
) -> list[Forecast]:
    """Valid rows of `version` whose tail has flights after the row's origin (among
    aircraft_ids if given): one index probe per row."""
    newer = exists().where(
        Flight.aircraft_id == Forecast.aircraft_id, Flight.flown_at > Forecast.origin
    )
    query = select(Forecast).where(valid_row(version, settings), newer)
    if aircraft_ids is None:
        return list(session.scalars(query))
    return [
        row
        for part in chunks(list(aircraft_ids))
        for row in session.scalars(query.where(Forecast.aircraft_id.in_(part)))
    ]


def fill_missing(
    session: Session, version: int, settings: Settings, aircraft_ids: Sequence[int] | None = None
) -> None:
    """Bring the rows of `version` (of aircraft_ids, default all) up to date: advance the rows
    behind their flights, recompute the missing ones and those that cannot advance.  One filler
    at a time per database and version in this process; what another filler stored meanwhile
    is kept."""
    if not missing(session, version, settings, aircraft_ids) and not behind(
        session, version, settings, aircraft_ids
    ):
        return
    with one_at_a_time(session, "rows", version):
        session.rollback()  # a fresh snapshot: rows the previous filler committed count
        stale = behind(session, version, settings, aircraft_ids)
        if stale:
            good, redo = cache_advance.advanceable(session, stale)
            model, posterior = model_service.load_model_and_posterior(session, version)
            cache_advance.advance(session, model, posterior, good, settings)
            invalidate_version(session, version, redo)
            session.commit()
        todo = missing(session, version, settings, aircraft_ids)
        if todo:
            refresh(session, version, settings, aircraft_ids=todo)


def invalidate_version(session: Session, version: int, aircraft_ids: Sequence[int]) -> None:
    """Drop the rows of these aircraft under `version` only (caller commits)."""
    for part in chunks(sorted(set(aircraft_ids))):
        session.execute(
            delete(Forecast).where(
                Forecast.model_version == version, Forecast.aircraft_id.in_(part)
            )
        )


def cached_state(session: Session, aircraft_id: int, version: int, settings: Settings) -> Forecast:
    """The tail's valid row, filled first where missing.  Raises ConflictError (no flights)."""

    def valid() -> Forecast | None:
        query = select(Forecast).where(
            Forecast.aircraft_id == aircraft_id, valid_row(version, settings)
        )
        return session.scalars(query).one_or_none()

    state = valid()
    if state is None or behind(session, version, settings, [aircraft_id]):
        fill_missing(session, version, settings, aircraft_ids=[aircraft_id])
        session.expire_all()
        state = valid()
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
) -> int:
    """Recompute the cached rows of these aircraft (default: all with flights) under `version`
    (app.services.cache_fill; `known`: a history the caller already read).  Returns the number
    of tails stored."""
    return cache_fill.fill(
        session, version, settings, aircraft_ids=aircraft_ids, progress=progress, known=known
    )
