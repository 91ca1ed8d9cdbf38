"""Forecasts: where each tail stands (cached per model version) and its projection from there.

The cache (table forecasts) holds, per tail and model version, the crack after the last recorded
flight, the tail's utilization and its time to critical; new flights or a new initial crack delete
a tail's rows.  A single forecast then only marches its horizon from the cached crack.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import numpy as np
import pandas as pd
import torch
from sqlalchemy import String, delete, exists, func, select, type_coerce
from sqlalchemy.orm import Session

from app.config import Settings
from app.errors import ConflictError
from app.services import models as model_service
from app.services.aircraft import find_aircraft
from app.services.records import stored_flights
from app.tables import Aircraft, Flight, Forecast
from model import forecast as fc
from model.records import assemble

_BATCH_AIRCRAFT = 100
_EPOCH = datetime(1970, 1, 1, tzinfo=UTC)


@dataclass(frozen=True)
class TrajectoryPoint:
    date: datetime
    flights: int
    crack_length_m: float


@dataclass(frozen=True)
class TailForecast:
    tail: str
    model_version: int
    origin: datetime
    flights_flown: int
    crack_length_m: float
    critical_crack_m: float
    flights_per_day: float
    horizon_days: int
    trajectory: list[TrajectoryPoint]
    flights_to_critical: int | None
    critical_date: datetime | None


@dataclass(frozen=True)
class RankedTail:
    tail: str
    crack_length_m: float
    flights_to_critical: int | None
    critical_date: datetime | None
    flights_flown: int
    origin: datetime
    flights_per_day: float


def _ns(value: datetime) -> int:
    return int(pd.Timestamp(value).as_unit("ns").value)


def _datetime(ns: int) -> datetime:
    return _EPOCH + timedelta(microseconds=ns // 1000)


def _search_cap(flights_per_day: float, settings: Settings) -> int:
    return int(settings.critical_search_years * 365.25 * flights_per_day)


def refresh(
    session: Session,
    version: int,
    settings: Settings,
    *,
    aircraft_ids: Sequence[int] | None = None,
    progress: Callable[[float], None] | None = None,
) -> int:
    """Recompute the cached state of these aircraft (default: all with flights) under `version`.

    Batches of aircraft march their whole histories together, then search their time to
    critical together (model.forecast.flights_to_critical).  Returns the number of tails stored.
    """
    model = model_service.load_model(session, version)
    law = model.spec.law
    if aircraft_ids is None:
        query = select(Aircraft.id).where(exists().where(Flight.aircraft_id == Aircraft.id))
        aircraft_ids = list(session.scalars(query.order_by(Aircraft.id)))
    ids = list(aircraft_ids)
    stored = 0
    for start in range(0, len(ids), _BATCH_AIRCRAFT):
        batch = ids[start : start + _BATCH_AIRCRAFT]
        stored += _refresh_batch(session, version, batch, model, law.critical_crack_m, settings)
        if progress is not None:
            progress(min(start + _BATCH_AIRCRAFT, len(ids)) / len(ids))
    return stored


def _refresh_batch(
    session: Session,
    version: int,
    aircraft_ids: list[int],
    model: model_service.CrackGrowthModel,
    critical_crack_m: float,
    settings: Settings,
) -> int:
    flights = stored_flights(session, aircraft_ids)
    if flights.empty:
        return 0
    data = assemble(flights)
    rows = session.execute(
        select(Aircraft.tail, Aircraft.id, Aircraft.initial_crack_m).where(
            Aircraft.id.in_(aircraft_ids)
        )
    )
    by_tail = {tail: (ident, initial) for tail, ident, initial in rows}
    a0 = model.spec.law.initial_crack_m
    initial = torch.tensor(
        [by_tail[t][1] or a0 for t in data.tails], dtype=torch.float64
    )  # (aircraft,)
    with torch.no_grad():
        trajectory = model.trajectory(data.loads, initial)  # (aircraft, flights + 1)
    lengths = data.loads.lengths
    crack_now = trajectory[torch.arange(len(data.tails)), lengths].tolist()

    ordered = data.flights
    times = ordered["flown_at"].dt.tz_convert(None).to_numpy("datetime64[ns]").view("int64")
    stress = ordered["stress_range_mpa"].to_numpy(dtype=np.float64)
    bounds = np.concatenate(([0], np.cumsum(lengths.numpy())))
    usage = [
        fc.recent_utilization(
            times[bounds[i] : bounds[i + 1]],
            stress[bounds[i] : bounds[i + 1]],
            settings.utilization_window_days,
        )
        for i in range(len(data.tails))
    ]
    to_critical = fc.flights_to_critical(
        model,
        crack_now,
        [u.recent_stress_mpa for u in usage],
        critical_crack_m,
        [_search_cap(u.flights_per_day, settings) for u in usage],
    )
    now = datetime.now(UTC)
    records = []
    for i, tail in enumerate(data.tails):
        origin_ns = int(times[bounds[i + 1] - 1])
        ttc = to_critical[i]
        rate = usage[i].flights_per_day
        records.append(
            Forecast(
                aircraft_id=by_tail[tail][0],
                model_version=version,
                computed_at=now,
                flights_flown=int(lengths[i]),
                first_flown_at=_datetime(int(times[bounds[i]])),
                origin=_datetime(origin_ns),
                crack_length_m=float(crack_now[i]),
                flights_per_day=rate,
                flights_to_critical=ttc,
                critical_date=None
                if ttc is None
                else _datetime(fc.date_after_flights(origin_ns, ttc, rate)),
            )
        )
    session.execute(
        delete(Forecast).where(
            Forecast.model_version == version, Forecast.aircraft_id.in_(aircraft_ids)
        )
    )
    session.add_all(records)
    session.commit()
    return len(records)


def _cached(session: Session, aircraft_id: int, version: int, settings: Settings) -> Forecast:
    state = session.get(Forecast, (aircraft_id, version))
    if state is None:
        refresh(session, version, settings, aircraft_ids=[aircraft_id])
        state = session.get(Forecast, (aircraft_id, version))
    if state is None:
        raise ConflictError("the tail has no recorded flights: a forecast starts at the last one")
    return state


def forecast_tail(
    session: Session, tail: str, *, horizon_days: int, settings: Settings
) -> TailForecast:
    """The tail's crack after its last flight and its projection horizon_days beyond it.

    Raises NotFoundError (unknown tail) or ConflictError (no active model, no flights).
    """
    aircraft = find_aircraft(session, tail)
    version = model_service.require_active_version(session)
    state = _cached(session, aircraft.id, version, settings)
    model = model_service.load_model(session, version)
    critical = model.spec.law.critical_crack_m

    window_start = state.origin - timedelta(days=settings.utilization_window_days)
    recent = session.connection().execute(
        select(type_coerce(Flight.flown_at, String), Flight.flight_id, Flight.stress_range_mpa)
        .where(
            Flight.aircraft_id == aircraft.id,
            Flight.flown_at > window_start,
            Flight.flown_at <= state.origin,  # the flights the cached state was computed from
        )
        .order_by(Flight.flown_at, Flight.flight_id)
    )
    cycle = np.array([row[2] for row in recent], dtype=np.float64)
    n = fc.flights_within(horizon_days, state.flights_per_day)
    future = torch.from_numpy(fc.project_loads(cycle, n)).unsqueeze(0)
    crack = torch.tensor([state.crack_length_m], dtype=torch.float64)
    trajectory = fc.march_ahead(model, crack, future)[0].numpy()  # (n + 1,)
    days, flights = fc.daily_points(trajectory, state.flights_per_day, horizon_days, critical)
    points = [
        TrajectoryPoint(
            date=state.origin + timedelta(days=int(d)),
            flights=state.flights_flown + int(k),
            crack_length_m=float(trajectory[k]),
        )
        for d, k in zip(days, flights, strict=True)
    ]
    return TailForecast(
        tail=aircraft.tail,
        model_version=version,
        origin=state.origin,
        flights_flown=state.flights_flown,
        crack_length_m=state.crack_length_m,
        critical_crack_m=critical,
        flights_per_day=state.flights_per_day,
        horizon_days=horizon_days,
        trajectory=points,
        flights_to_critical=state.flights_to_critical,
        critical_date=state.critical_date,
    )


# Most urgent first: the earliest critical date (none within the search cap: last), then the
# largest crack now.
_URGENCY = (
    Forecast.critical_date.is_(None),
    Forecast.critical_date,
    Forecast.crack_length_m.desc(),
    Aircraft.tail,
)


def _missing(session: Session, version: int) -> list[int]:
    query = select(Aircraft.id).where(
        exists().where(Flight.aircraft_id == Aircraft.id),
        ~exists().where(Forecast.aircraft_id == Aircraft.id, Forecast.model_version == version),
    )
    return list(session.scalars(query))


def ranking(
    session: Session, *, limit: int, settings: Settings
) -> tuple[int, float, int, list[RankedTail]]:
    """Tails most urgent first: earliest critical date, then largest crack.

    Fills the cache for tails whose state is missing (new flights) first.  Returns
    (model version, critical crack, tails ranked in all, the first `limit`).
    """
    version = model_service.require_active_version(session)
    missing = _missing(session, version)
    if missing:
        refresh(session, version, settings, aircraft_ids=missing)
    critical = model_service.load_model(session, version).spec.law.critical_crack_m
    base = (
        select(Forecast, Aircraft.tail)
        .join(Aircraft, Aircraft.id == Forecast.aircraft_id)
        .where(Forecast.model_version == version)
    )
    rows = session.execute(
        base.order_by(
            *_URGENCY,
        ).limit(limit)
    )
    items = [
        RankedTail(
            tail=tail,
            crack_length_m=f.crack_length_m,
            flights_to_critical=f.flights_to_critical,
            critical_date=f.critical_date,
            flights_flown=f.flights_flown,
            origin=f.origin,
            flights_per_day=f.flights_per_day,
        )
        for f, tail in rows
    ]
    total = session.scalar(
        select(func.count()).select_from(Forecast).where(Forecast.model_version == version)
    )
    return version, critical, total or 0, items


EXPORT_COLUMNS = [
    "rank",
    "tail",
    "model_version",
    "flights_flown",
    "origin",
    "crack_length_m",
    "flights_per_day",
    "flights_to_critical",
    "critical_date",
    "computed_at",
]


def export_frame(session: Session, version: int) -> pd.DataFrame:
    """Stored forecasts of a version, most urgent first, as a table for CSV/Parquet export."""
    rows = session.execute(
        select(Aircraft.tail, Forecast)
        .join(Aircraft, Aircraft.id == Forecast.aircraft_id)
        .where(Forecast.model_version == version)
        .order_by(
            *_URGENCY,
        )
    )
    frame = pd.DataFrame(
        [
            {
                "rank": rank,
                "tail": tail,
                "model_version": version,
                "flights_flown": f.flights_flown,
                "origin": f.origin,
                "crack_length_m": f.crack_length_m,
                "flights_per_day": f.flights_per_day,
                "flights_to_critical": f.flights_to_critical,
                "critical_date": f.critical_date,
                "computed_at": f.computed_at,
            }
            for rank, (tail, f) in enumerate(rows, start=1)
        ],
        columns=EXPORT_COLUMNS,
    )
    return frame.astype({"flights_to_critical": "Int64"})


def run_batch(
    session: Session, *, version: int | None, settings: Settings, progress: Callable[[float], None]
) -> dict[str, object]:
    """Forecast the whole fleet under `version` (default: the active one) and store the results."""
    version = version or model_service.require_active_version(session)
    model_service.get_version(session, version)
    stored = refresh(session, version, settings, progress=progress)
    return {"model_version": version, "forecasts": stored}
