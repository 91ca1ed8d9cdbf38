"""The forecast cache's rows (table forecasts): the one module that writes them and says when
one is valid (the ranking's reads of them: app.services.ranking.ranking_rows).

A row holds where one subject (a location of a tail: Subject) stands under one model version; app.services.
forecasts.forecast_cache says when a row is valid and who keeps it so.  The modules that compute rows
(cache_fill from a whole history, cache_advance over new flights, risk's sampling) work on
CacheState, a plain record, and hand it here to be stored: so a write is one of a few
statements below (replace a subject's rows, update one only where it is still the state that
was read, drop), and readers get snapshots an ingest cannot change under them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields
from datetime import datetime
from typing import Any, cast

import numpy as np
from sqlalchemy import (
    ColumnElement,
    and_,
    delete,
    exists,
    func,
    select,
    update,
)
from sqlalchemy.orm import Session, defer
from torch import Tensor

from app.config import Settings
from app.services.dates import from_ns
from app.services.records.carriage import carries
from app.storage import chunks
from app.tables import DEFAULT_LOCATION_ID, Aircraft, Flight, Forecast, ModelVersion
from model import forecast as fc


@dataclass(frozen=True)
class Subject:
    """What a forecast tracks: one location (the catalogue's, app.services.records.locations) of one
    aircraft.  An aircraft's flights move all its subjects; an inspection, one."""

    aircraft_id: int
    location_id: int = DEFAULT_LOCATION_ID


@dataclass
class CacheState:
    """Where a subject stands after its last recorded flight (its origin) under one version:
    the crack under the fitted weights and under every posterior draw (crack_samples_m,
    float64 bytes (samples,)), its growth factor's draws (growth_samples, ln factor), its
    utilization and the recent stress ranges future usage is resampled from, its time to
    critical, and per "lead+horizon" key the sampled risk and daily bands (app.services.forecasts.risk).
    bands None: pending (cache_advance.fill_pending samples them).  stamp: the stored row's
    (None until stored)."""

    aircraft_id: int
    location_id: int
    model_version: int
    computed_at: datetime
    flights_flown: int
    first_flown_at: datetime
    origin: datetime
    crack_length_m: float
    flights_per_day: float
    flights_to_critical: int | None
    critical_date: datetime | None
    crack_samples_m: bytes | None
    recent_stress_mpa: bytes | None
    risk: dict[str, Any] | None
    bands: dict[str, Any] | None
    growth_samples: bytes | None
    growth: dict[str, Any] | None
    stamp: int | None = None


def standing(
    origin_ns: int,
    crack_now_m: float,
    crack_samples_m: Tensor,
    to_critical: int | None,
    usage: fc.Utilization,
) -> dict[str, Any]:
    """CacheState's fields of where a subject stands after its origin (epoch ns): its crack and
    every draw's, its utilization and recent ranges, its flights and date to critical, derived
    alike by the fill (cache_fill) and the advance (cache_advance)."""
    rate = usage.flights_per_day
    return {
        "origin": from_ns(origin_ns),
        "crack_length_m": float(crack_now_m),
        "flights_per_day": rate,
        "flights_to_critical": to_critical,
        "critical_date": None
        if to_critical is None
        else from_ns(fc.date_after_flights(origin_ns, to_critical, rate)),
        "crack_samples_m": crack_samples_m.numpy().tobytes(),
        "recent_stress_mpa": usage.recent_stress_mpa.astype(np.float64).tobytes(),
    }


_COLUMNS = tuple(f.name for f in fields(CacheState) if f.name != "stamp")
# what an advance moves (the growth posterior stays: no new inspection)
_ADVANCED = (
    "computed_at",
    "flights_flown",
    "origin",
    "crack_length_m",
    "flights_per_day",
    "flights_to_critical",
    "critical_date",
    "crack_samples_m",
    "recent_stress_mpa",
    "risk",
    "bands",
)


def state_of(row: Forecast) -> CacheState:
    """A stored row as a plain record (bands deferred and unread count as pending)."""
    values: dict[str, Any] = {name: getattr(row, name) for name in _COLUMNS if name != "bands"}
    return CacheState(**values, bands=row.__dict__.get("bands"), stamp=row.stamp)


def _key(state: CacheState) -> ColumnElement[bool]:
    return and_(
        Forecast.aircraft_id == state.aircraft_id,
        Forecast.location_id == state.location_id,
        Forecast.model_version == state.model_version,
    )


def _unchanged(state: CacheState) -> ColumnElement[bool]:
    """The stored row is still the state that was read (same origin and flight count)."""
    return and_(
        _key(state),
        Forecast.origin == state.origin,
        Forecast.flights_flown == state.flights_flown,
    )


# --- reads ------------------------------------------------------------------------------------


def valid_row(version: int, settings: Settings) -> ColumnElement[bool]:
    """Rows that serve `version` under these settings: filled with forecast_samples samples.
    (A version serves one location, app.services.models.location_of: its rows are that
    location's.)"""
    return and_(
        Forecast.model_version == version,
        func.length(Forecast.crack_samples_m) == 8 * settings.forecast_samples,
    )


def valid_state(
    session: Session, subject: Subject, version: int, settings: Settings, *, bands: bool = True
) -> CacheState | None:
    """The subject's valid row of `version` as a snapshot, None where missing; without
    `bands` its bands are not read (they count as pending: tens of KB of JSON a decision does
    not need)."""
    query = select(Forecast).where(
        Forecast.aircraft_id == subject.aircraft_id,
        Forecast.location_id == subject.location_id,
        valid_row(version, settings),
    )
    if not bands:
        query = query.options(defer(Forecast.bands))
    row = session.scalars(query).one_or_none()
    return None if row is None else state_of(row)


def missing(
    session: Session,
    version: int,
    settings: Settings,
    aircraft_ids: Sequence[int] | None = None,
) -> list[int]:
    """Aircraft with flights and no valid row of `version` (among aircraft_ids if given)."""
    cached = exists().where(Forecast.aircraft_id == Aircraft.id, valid_row(version, settings))
    location = select(ModelVersion.location_id).where(ModelVersion.version == version)
    query = select(Aircraft.id).where(
        exists().where(Flight.aircraft_id == Aircraft.id),
        carries(location.scalar_subquery()),  # the aircraft carrying the version's location
        ~cached,
    )
    if aircraft_ids is None:
        return list(session.scalars(query))
    return [
        i
        for part in chunks(list(aircraft_ids))
        for i in session.scalars(query.where(Aircraft.id.in_(part)))
    ]


def locked(session: Session, aircraft_ids: Sequence[int]) -> list[CacheState]:
    """Every row (any version) of these aircraft, held for update until the caller commits."""
    return [
        state_of(row)
        for part in chunks(list(aircraft_ids))
        for row in session.scalars(
            select(Forecast).where(Forecast.aircraft_id.in_(part)).with_for_update()
        )
    ]


def behind(session: Session, version: int, aircraft_ids: Sequence[int]) -> list[CacheState]:
    """Rows of `version` among aircraft_ids whose tail has flights after the row's origin (each
    probe reads its tail's flights: for the tails a writer touched, never the whole fleet)."""
    newer = exists().where(
        Flight.aircraft_id == Forecast.aircraft_id, Flight.flown_at > Forecast.origin
    )
    query = select(Forecast).where(Forecast.model_version == version, newer)
    return [
        state_of(row)
        for part in chunks(sorted(set(aircraft_ids)))
        for row in session.scalars(query.where(Forecast.aircraft_id.in_(part)))
    ]


def pending(session: Session, settings: Settings, limit: int) -> list[CacheState]:
    """Up to `limit` rows stored without bands (oldest first), of the current sample count."""
    size = 8 * settings.forecast_samples
    query = (
        select(Forecast)
        .where(Forecast.bands.is_(None), func.length(Forecast.crack_samples_m) == size)
        .order_by(Forecast.computed_at)
        .limit(limit)
    )
    return [state_of(row) for row in session.scalars(query)]


def active_stamp(
    session: Session, tail: str, location_id: int = DEFAULT_LOCATION_ID
) -> tuple[int, int] | None:
    """(the active version, the stamp of the tail's row of it at the location) in one query;
    None where the tail, an active version or a stamped row is missing."""
    query = (
        select(ModelVersion.version, Forecast.stamp)
        .select_from(Aircraft)
        .join(
            ModelVersion,
            (ModelVersion.status == "active") & (ModelVersion.location_id == location_id),
        )
        .outerjoin(
            Forecast,
            (Forecast.aircraft_id == Aircraft.id)
            & (Forecast.location_id == location_id)
            & (Forecast.model_version == ModelVersion.version),
        )
        .where(Aircraft.tail == tail)
    )
    found = session.connection().execute(query).one_or_none()
    if found is None or found.stamp is None:
        return None
    return cast(tuple[int, int], (found.version, found.stamp))


# --- writes (the caller commits) ----------------------------------------------------------------


def drop_version(
    session: Session, version: int, aircraft_ids: Sequence[int], location_id: int
) -> None:
    """Drop the rows of `version` of these aircraft at the location (a fill, before it stores
    them anew)."""
    for part in chunks(sorted(set(aircraft_ids))):
        session.execute(
            delete(Forecast).where(
                Forecast.model_version == version,
                Forecast.location_id == location_id,
                Forecast.aircraft_id.in_(part),
            )
        )


def add(session: Session, states: Sequence[CacheState]) -> None:
    """Store new rows (none of their aircraft and version may be stored)."""
    session.add_all(Forecast(**{name: getattr(s, name) for name in _COLUMNS}) for s in states)
    session.flush()


def store_advanced(session: Session, read: CacheState, advanced: CacheState) -> int:
    """Store an advanced state over the row it was advanced from, only where that row is still
    the one read (so two fillers never advance a row twice).  Returns the rows written."""
    values = {name: getattr(advanced, name) for name in _ADVANCED}
    changed = session.execute(
        update(Forecast)
        .where(_unchanged(read))
        .values(values)
        .execution_options(synchronize_session=False)
    )
    return int(changed.rowcount)  # type: ignore[attr-defined]


def store_risk(session: Session, states: Sequence[CacheState], *, bands: bool) -> int:
    """Write the risk (and with `bands` the bands) of these states to their rows, each only
    where the row is still the one sampled (same origin and flight count, and its stamp where
    the state has one): a row an ingest advanced or dropped meanwhile keeps what it has.

    The row keeps its stamp: what is written was sampled from the row's own state (seeded per
    tail, app.services.forecasts.risk), so an answer kept under the stamp is what its reader would make
    from the row now; a new stamp made every process answer anew after the worker sampled
    tomorrow's risk of a tail just ingested.  Returns the rows written."""
    written = 0
    for state in states:
        values: dict[str, Any] = {"risk": state.risk}
        if bands:
            values["bands"] = state.bands
        where = _unchanged(state)
        if state.stamp is not None:
            where = and_(where, Forecast.stamp == state.stamp)
            values["stamp"] = state.stamp
        changed = session.execute(
            update(Forecast)
            .where(where)
            .values(values)
            .execution_options(synchronize_session=False)
        )
        written += changed.rowcount  # type: ignore[attr-defined]
    return written


def drop(session: Session, aircraft_ids: Sequence[int]) -> None:
    """Drop the rows of these aircraft at every location under every version."""
    for part in chunks(sorted(set(aircraft_ids))):
        session.execute(delete(Forecast).where(Forecast.aircraft_id.in_(part)))


def drop_subjects(session: Session, subjects: Sequence[Subject]) -> None:
    """Drop the rows of these subjects under every version."""
    for subject in subjects:
        session.execute(
            delete(Forecast).where(
                Forecast.aircraft_id == subject.aircraft_id,
                Forecast.location_id == subject.location_id,
            )
        )


def drop_location(session: Session, location_id: int) -> None:
    """Drop every row of the location (its catalogue entry changed)."""
    session.execute(delete(Forecast).where(Forecast.location_id == location_id))


def drop_outdated(session: Session, aircraft_id: int, first_new: datetime) -> None:
    """Drop the aircraft's rows that new flights from `first_new` cannot advance: those whose
    origin lies at or after it."""
    outdated = Forecast.origin >= first_new
    session.execute(delete(Forecast).where(Forecast.aircraft_id == aircraft_id, outdated))


def drop_states(session: Session, states: Sequence[CacheState]) -> None:
    """Drop the rows of these states (their aircraft and version)."""
    for state in states:
        session.execute(
            delete(Forecast).where(_key(state)).execution_options(synchronize_session=False)
        )
