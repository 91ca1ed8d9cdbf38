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
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from typing import Any

import numpy as np
import pandas as pd
import torch
from sqlalchemy import ColumnElement, and_, delete, exists, func, select
from sqlalchemy.orm import Session

from app.config import Settings
from app.errors import ConflictError
from app.services import cache_advance
from app.services import models as model_service
from app.services.history import History, load_history
from app.services.risk import fill_risk, from_ns, tail_seed
from app.storage import chunks
from app.tables import Aircraft, Flight, Forecast
from model import forecast as fc
from model.fleet_sampling import crack_samples
from model.hybrid import CrackGrowthModel
from model.tracking import TailEvidence, TrackingPrior, growth_posterior
from model.uncertainty import LaplacePosterior

_BATCH_AIRCRAFT = 100
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
    for aircraft_id, flown_at in earliest.items():
        session.execute(
            delete(Forecast).where(
                Forecast.aircraft_id == int(aircraft_id),
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
) -> int:
    """Recompute the cached rows of these aircraft (default: all with flights) under `version`.

    Batches of aircraft march their histories (from their last repair) together, under the
    fitted weights and under each posterior sample, search their time to critical together
    (model.forecast.flights_to_critical) and sample their risk over forecast_horizon_days.
    Returns the number of tails stored.
    """
    model, posterior = model_service.load_model_and_posterior(session, version)
    prior = model_service.tracking_prior(session, version)
    if aircraft_ids is None:
        query = select(Aircraft.id).where(exists().where(Flight.aircraft_id == Aircraft.id))
        aircraft_ids = list(session.scalars(query.order_by(Aircraft.id)))
    ids = list(aircraft_ids)
    stored = 0
    for start in range(0, len(ids), _BATCH_AIRCRAFT):
        batch = ids[start : start + _BATCH_AIRCRAFT]
        stored += _refresh_batch(session, version, batch, model, posterior, prior, settings)
        if progress is not None:
            progress(min(start + _BATCH_AIRCRAFT, len(ids)) / len(ids))
    return stored


def _refresh_batch(
    session: Session,
    version: int,
    aircraft_ids: list[int],
    model: CrackGrowthModel,
    posterior: LaplacePosterior | None,
    prior: TrackingPrior | None,
    settings: Settings,
) -> int:
    law = model.spec.law
    history = load_history(session, aircraft_ids, initial_crack_m=law.initial_crack_m)
    if history is None:
        return 0
    data, segments = history.data, history.segments
    growth = _growth(model, history, prior, settings)
    since_repair = segments.loads.select(torch.from_numpy(segments.last))  # (tails, flights)
    if growth is not None:
        since_repair = replace(since_repair, growth_factor=growth.point)
    start_crack = since_repair.initial_or(law.initial_crack_m)
    with torch.no_grad():
        trajectory = model.trajectory(since_repair, start_crack)  # (tails, flights + 1)
    crack_now = trajectory[torch.arange(len(data.tails)), since_repair.lengths].tolist()
    cracks = crack_samples(
        model,
        posterior,
        since_repair,
        start_crack,
        samples=settings.forecast_samples,
        seed=settings.forecast_seed,
        growth_factor=None if growth is None else torch.exp(growth.samples),
    )
    lengths = data.loads.lengths
    times = data.flights["flown_at"].dt.tz_convert(None).to_numpy("datetime64[ns]").view("int64")
    stress = data.flights["stress_range_mpa"].to_numpy(dtype=np.float64)
    bounds = np.concatenate(([0], np.cumsum(lengths.numpy())))
    usage = [
        fc.recent_utilization(
            times[bounds[i] : bounds[i + 1]],
            stress[bounds[i] : bounds[i + 1]],
            settings.utilization_window_days,
        )
        for i in range(len(data.tails))
    ]
    search_cap = [int(settings.critical_search_years * 365.25 * u.flights_per_day) for u in usage]
    to_critical = fc.flights_to_critical(
        model,
        crack_now,
        [u.recent_stress_mpa for u in usage],
        law.critical_crack_m,
        search_cap,
        growth_factor=None if growth is None else growth.point.tolist(),
    )
    now = datetime.now(UTC)
    repaired = history.last_repair_ns()
    records = []
    for i, aircraft_id in enumerate(history.aircraft_ids):
        origin_ns = max(int(times[bounds[i + 1] - 1]), repaired.get(data.tails[i], 0))
        ttc, rate = to_critical[i], usage[i].flights_per_day
        records.append(
            Forecast(
                aircraft_id=aircraft_id,
                model_version=version,
                computed_at=now,
                flights_flown=int(lengths[i]),
                first_flown_at=from_ns(int(times[bounds[i]])),
                origin=from_ns(origin_ns),
                crack_length_m=float(crack_now[i]),
                flights_per_day=rate,
                flights_to_critical=ttc,
                critical_date=None
                if ttc is None
                else from_ns(fc.date_after_flights(origin_ns, ttc, rate)),
                crack_samples_m=cracks[:, i].numpy().tobytes(),
                recent_stress_mpa=usage[i].recent_stress_mpa.astype(np.float64).tobytes(),
                risk={},
                bands={},
                growth_samples=None if growth is None else growth.samples[:, i].numpy().tobytes(),
                growth=None if growth is None else growth.summary[i],
            )
        )
    fill_risk(
        model,
        posterior,
        records,
        settings.forecast_horizon_days,
        settings,
        bands=True,
        as_of=settings.today(),
    )
    session.execute(
        delete(Forecast).where(
            Forecast.model_version == version, Forecast.aircraft_id.in_(aircraft_ids)
        )
    )
    session.add_all(records)
    session.commit()
    return len(records)


@dataclass(frozen=True)
class _TailGrowth:
    """Each tail's growth posterior (model.tracking) for the cache: samples (samples, tails) of
    ln factor, the point factor (its median, (tails,)) and a summary with the evidence."""

    samples: torch.Tensor
    point: torch.Tensor
    summary: list[dict[str, Any]]


def _growth(
    model: CrackGrowthModel, history: History, prior: TrackingPrior | None, settings: Settings
) -> _TailGrowth | None:
    """The tails' growth posteriors from their own inspections (all segments, repairs too);
    None for versions without tracking.  Each tail's draws use its own seed, so a tail's
    forecast does not depend on which tails were refreshed with it."""
    if prior is None:
        return None
    segments = history.segments
    tails = len(history.data.tails)
    evidence = TailEvidence(
        segments.loads, torch.from_numpy(segments.tail), segments.observations, tails
    )
    posterior = growth_posterior(model, evidence, prior)
    samples = torch.stack(
        [
            posterior.select(torch.tensor([i])).sample(
                settings.forecast_samples, tail_seed(settings, history.aircraft_ids[i])
            )[:, 0]
            for i in range(tails)
        ],
        dim=1,
    )
    quantiles = posterior.factor_quantiles((0.05, 0.5, 0.95))
    inspections = history.inspections
    summary = []
    for i, tail in enumerate(history.data.tails):
        mine = inspections[inspections["tail"] == tail]
        summary.append(
            {
                "p05": float(quantiles[i, 0]),
                "p50": float(quantiles[i, 1]),
                "p95": float(quantiles[i, 2]),
                "fleet_growth_sd": prior.growth_sd,
                "sizing_relative_sd": prior.sizing.relative_sd,
                "inspection_ids": mine["inspection_id"].astype(str).tolist(),
            }
        )
    return _TailGrowth(samples, quantiles[:, 1].clone(), summary)
