"""Filling the forecast cache from scratch: each tail's whole history, marched in batches.

Batches of tails march their histories (from their last repair) together, under the fitted
weights and under each posterior sample, search their time to critical together
(model.forecast.flights_to_critical) and sample their risk over forecast_horizon_days, with the
daily bands as of today and the risk alone as of tomorrow too (risk.days_ahead).

A retrain hands over what it already has (Known): the history it read and the growth
posteriors of the tails it trained on (model.tracking_fit.TrackedFit.posterior: the same
function of a tail's own inspections as here), so the 2.19 M flights are not read twice and
only the other tails' posteriors are computed.

What changed while a batch was computed is not stored as current (app.services.forecasts.forecast_cache
says how rows stay valid): rows behind flights appended after their origin are advanced before
the commit (app.services.forecasts.cache_advance.catch_up); a flight added at or before the origin, and a
corrected or deleted record, a new inspection or initial crack (audit events after
`since_event`) leave their tail's row out, for the next reader to recompute.  The checks run
after the batch's tails are locked (the delete's write lock on SQLite, their aircraft rows FOR
UPDATE on PostgreSQL, which waits for ingests of them in flight), so no writer slips in between
until the commit.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from typing import Any

import numpy as np
import torch
from sqlalchemy import exists, func, select
from sqlalchemy.orm import Session

from app import budget
from app.config import Settings
from app.services import models as model_service
from app.services.dates import days_ahead, from_ns
from app.services.forecasts import cache_advance, cache_rows
from app.services.forecasts.cache_rows import CacheState
from app.services.forecasts.risk import fill_risk, tail_seed
from app.services.records.carriage import carries
from app.services.records.history import History, load_history
from app.services.records.stored_spectra import with_stored_cycles
from app.tables import Aircraft, AuditEvent, Flight
from model import forecast as fc
from model.posterior import GrowthPosterior, LocationPosterior, TailEvidence, select_rows

_BATCH_AIRCRAFT = 100
# Audit actions after which a tail's row must be recomputed (flight ingests are checked by
# counting flights instead: appends advance).
_VOIDING = (
    "flight.correct",
    "flight.delete",
    "inspection.correct",
    "inspection.delete",
    "inspections.ingest",
    "aircraft.update",
)


@dataclass(frozen=True)
class Known:
    """What a caller already read: `history` (read after audit event `since_event`) and, where
    given, growth posteriors of some of its tails: row j of `growth` is history tail
    growth_tails[j]."""

    history: History
    since_event: int
    growth: GrowthPosterior | None = None
    growth_tails: np.ndarray | None = None


def audit_mark(session: Session) -> int:
    """The latest audit event's id (0: none): read before a history, checked when storing."""
    return int(session.scalar(select(func.max(AuditEvent.id))) or 0)


def fill(
    session: Session,
    version: int,
    settings: Settings,
    *,
    aircraft_ids: Sequence[int] | None = None,
    progress: Callable[[float], None] | None = None,
    known: Known | None = None,
    ahead: bool = True,
) -> int:
    """Recompute the cached rows of these aircraft (default: all with flights) under `version`,
    at the location it serves; returns the number of tails stored.  ahead: store tomorrow's risk too (risk.days_ahead);
    a retrain leaves it to the worker's warm of the new version (app.worker), off its clock."""
    posterior = model_service.load_posterior(session, version)
    location_id = model_service.location_of(session, version)
    if aircraft_ids is None:
        query = select(Aircraft.id).where(
            exists().where(Flight.aircraft_id == Aircraft.id), carries(location_id)
        )
        aircraft_ids = list(session.scalars(query.order_by(Aircraft.id)))
    ids = list(aircraft_ids)
    total, stored = len(ids), 0
    if (
        known is not None
        and known.history.location_id == location_id
        and set(known.history.aircraft_ids) <= set(ids)
    ):
        known = replace(known, history=_under(session, posterior, known.history))
        growth = None if posterior.tracking is None else _growth(posterior, known, settings)
        stored += _store(
            session,
            version,
            known.history,
            known.since_event,
            posterior,
            growth,
            settings,
            ahead,
        )
        taken = set(known.history.aircraft_ids)
        ids = [i for i in ids if i not in taken]
        if progress is not None and total:
            progress((total - len(ids)) / total)
    for start in range(0, len(ids), _BATCH_AIRCRAFT):
        budget.check()  # a request out of time stops here; the batches stored stay
        batch = ids[start : start + _BATCH_AIRCRAFT]
        mark = audit_mark(session)
        read = load_history(
            session,
            batch,
            initial_crack_m=posterior.law.initial_crack_m,
            location_id=location_id,
        )
        if read is not None:
            read = _under(session, posterior, read)
            tracked = posterior.tracking is not None
            growth = _growth(posterior, Known(read, mark), settings) if tracked else None
            stored += _store(session, version, read, mark, posterior, growth, settings, ahead)
        if progress is not None:
            progress((total - len(ids) + min(start + _BATCH_AIRCRAFT, len(ids))) / total)
    return stored


def _under(session: Session, posterior: LocationPosterior, history: History) -> History:
    """The history's stored cycles reduced under the version's own law (a learned gamma or m
    weighs them as the fit did; app.services.records.stored_spectra); as read where none are stored."""
    return with_stored_cycles(session, history, posterior.growth_law, posterior.law.constants)


def _store(
    session: Session,
    version: int,
    history: History,
    since_event: int,
    posterior: LocationPosterior,
    growth: _TailGrowth | None,
    settings: Settings,
    ahead: bool = True,
) -> int:
    """Store the rows of `history`'s tails: the crack now under every sample (its growth
    factor, its weights and the extrapolation beyond the measured cracks; its path's drift is
    drawn where forecasts are sampled, app.services.forecasts.risk), the point values and the default
    horizon's risk."""
    law = posterior.law
    data, segments = history.data, history.segments
    since_repair = segments.loads.select(torch.from_numpy(segments.last))  # (tails, flights)
    if growth is not None:
        since_repair = replace(since_repair, growth_factor=growth.point)
    start_crack = since_repair.initial_or(law.initial_crack_m)
    trajectory = posterior.trajectory(since_repair, start_crack)  # (tails, flights + 1)
    crack_now = trajectory[torch.arange(len(data.tails)), since_repair.lengths].tolist()
    cracks = posterior.crack_now(
        since_repair,
        start_crack,
        samples=settings.forecast_samples,
        seed=settings.forecast_seed,
        log_growth=None if growth is None else growth.samples,
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
            settings.load_window_days,
        )
        for i in range(len(data.tails))
    ]
    search_cap = [int(settings.critical_search_years * 365.25 * u.flights_per_day) for u in usage]
    to_critical = posterior.flights_to_critical(
        crack_now,
        [u.recent_stress_mpa for u in usage],
        search_cap,
        growth_factor=None if growth is None else growth.point.tolist(),
    )
    now = datetime.now(UTC)
    repaired = history.last_repair_ns()
    records = []
    for i, aircraft_id in enumerate(history.aircraft_ids):
        origin_ns = max(int(times[bounds[i + 1] - 1]), repaired.get(data.tails[i], 0))
        records.append(
            CacheState(
                aircraft_id=aircraft_id,
                location_id=history.location_id,
                model_version=version,
                computed_at=now,
                flights_flown=int(lengths[i]),
                first_flown_at=from_ns(int(times[bounds[i]])),
                **cache_rows.standing(
                    origin_ns, float(crack_now[i]), cracks[:, i], to_critical[i], usage[i]
                ),
                risk={},
                bands={},
                growth_samples=None if growth is None else growth.samples[:, i].numpy().tobytes(),
                growth=None if growth is None else growth.summary[i],
            )
        )
    today, tomorrow = days_ahead(settings)
    horizon = settings.forecast_horizon_days
    fill_risk(posterior, records, horizon, settings, bands=True, as_of=today)
    if ahead:
        fill_risk(posterior, records, horizon, settings, bands=False, as_of=tomorrow)
    ids = list(history.aircraft_ids)
    session.execute(select(Aircraft.id).where(Aircraft.id.in_(ids)).with_for_update())
    cache_rows.drop_version(
        session, version, ids, history.location_id
    )  # on SQLite, the write lock from here on
    voided = _voided_since(session, since_event, dict(zip(data.tails, ids, strict=True)))
    current = [
        r
        for r in records
        if r.aircraft_id not in voided and _flights_up_to(session, r) == r.flights_flown
    ]
    cache_rows.add(session, current)
    behind = cache_rows.behind(session, version, [r.aircraft_id for r in current])
    cache_advance.catch_up(session, behind, settings)
    session.commit()
    return len(current)


def _flights_up_to(session: Session, record: CacheState) -> int:
    """The tail's flights up to the record's origin now: more than it counted means a flight
    was added before the origin since the history was read."""
    return int(
        session.scalar(
            select(func.count())
            .select_from(Flight)
            .where(Flight.aircraft_id == record.aircraft_id, Flight.flown_at <= record.origin)
        )
        or 0
    )


def _voided_since(session: Session, since_event: int, ids_by_tail: dict[str, int]) -> set[int]:
    """Aircraft among ids_by_tail whose records changed otherwise than by appended flights since
    audit event since_event (an event naming more tails than it lists voids them all)."""
    voided: set[int] = set()
    events = session.execute(
        select(AuditEvent.action, AuditEvent.subject, AuditEvent.detail).where(
            AuditEvent.id > since_event, AuditEvent.action.in_(_VOIDING)
        )
    )
    for action, subject, detail in events:
        tail = subject.split("/", 1)[0]
        if tail in ids_by_tail:
            voided.add(ids_by_tail[tail])
            continue
        named = (detail or {}).get("tails") or []
        voided.update(ids_by_tail[t] for t in named if t in ids_by_tail)
        some = action == "inspections.ingest" and subject.endswith(" tails")
        if some and int(subject.split()[0]) > len(named):
            return set(ids_by_tail.values())
    return voided


@dataclass(frozen=True)
class _TailGrowth:
    """Each tail's growth posterior (model.tracking) for the cache: samples (samples, tails) of
    ln factor, the point factor (its median, (tails,)) and a summary with the evidence."""

    samples: torch.Tensor
    point: torch.Tensor
    summary: list[dict[str, Any]]


def _growth(posterior: LocationPosterior, known: Known, settings: Settings) -> _TailGrowth:
    """The tails' growth posteriors from their own inspections (all segments, repairs too),
    those `known` gives taken as they are.  Each tail's draws use its own seed, so a tail's
    forecast does not depend on which tails were refreshed with it."""
    history = known.history
    prior = posterior.tracking
    assert prior is not None
    growth = posterior.tail_growth(
        _posteriors(posterior, known),
        settings.forecast_samples,
        [tail_seed(settings, aircraft_id) for aircraft_id in history.aircraft_ids],
    )
    quantiles = growth.quantiles
    inspections = history.inspections
    segments = history.segments
    since = posterior.drift_origins(segments.loads, segments.observations)
    since = since[torch.from_numpy(segments.last)]
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
                # where its forecast's drift counts from (app.services.forecasts.risk)
                "since_crack_m": float(since[i]),
            }
        )
    return _TailGrowth(growth.samples, growth.point, summary)


def _posteriors(posterior: LocationPosterior, known: Known) -> GrowthPosterior:
    """(tails,) growth posteriors of known.history's tails: the known ones, the others computed
    (a tail's posterior depends on its own inspections only)."""
    history, segments = known.history, known.history.segments
    tails = len(history.data.tails)
    have = (
        np.zeros(0, dtype=np.int64)
        if known.growth is None or known.growth_tails is None
        else np.asarray(known.growth_tails, dtype=np.int64)
    )
    todo = np.setdiff1d(np.arange(tails), have)
    computed = None
    if len(todo):
        rows = np.flatnonzero(np.isin(segments.tail, todo))
        loads, observations = select_rows(segments.loads, segments.observations, rows)
        _, row_tail = np.unique(segments.tail[rows], return_inverse=True)
        evidence = TailEvidence(loads, torch.from_numpy(row_tail), observations, len(todo))
        computed = posterior.update(evidence)
    if computed is not None and (known.growth is None or not len(have)):
        return computed
    assert known.growth is not None
    if computed is None:
        order = np.argsort(have)
        return known.growth.select(torch.from_numpy(order))
    if computed.z.shape[1] != known.growth.z.shape[1]:
        raise AssertionError("growth posteriors on grids of different sizes")
    z = torch.empty(tails, computed.z.shape[1], dtype=computed.z.dtype)
    mass = torch.empty_like(z)
    z[torch.from_numpy(have)], mass[torch.from_numpy(have)] = known.growth.z, known.growth.mass
    z[torch.from_numpy(todo)], mass[torch.from_numpy(todo)] = computed.z, computed.mass
    return GrowthPosterior(z, mass)
