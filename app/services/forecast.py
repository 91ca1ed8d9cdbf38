"""Forecasts: where each tail stands (cached per model version) and its projection from there.

The cache (table forecasts) holds, per tail and model version, the crack after the last recorded
flight, the tail's utilization and its time to critical; new flights, a new initial crack or a
repair delete a tail's rows.  A single forecast then only marches its horizon from the cached
crack.  The crack marches from the tail's last repair (app.services.segments) if it has one.

Uncertainty (model.uncertainty.probabilistic_forecast) has two sources, sampled together:
sample k pairs posterior weight draw theta_k (the version's Laplace posterior; versions stored
without one have no model uncertainty) with future usage draw k (ResampledLoads: blocks of one
day of the tail's own recent flights; or a planned utilization, PlannedLoads).  The model's
uncertainty about the crack *now* is kept: the cache holds the crack after the last flight under
every theta_k (crack_samples_m: one compiled march of the history per sample over a batch of
tails, done when the row is filled), and sample k's future march starts from its own entry.
Marching the 7,300-flight history per request instead would cost samples x 3.4 ms (a single lane
of the compiled march), about 0.7 s at 200 samples.  The sampled summary (crack band now,
P(critical within the horizon), flights-to-critical quantiles, inspect-by) and the daily bands
are cached per horizon in the row (risk, bands): the retrain and the batch job fill them for
forecast_horizon_days, a request for another horizon fills its own once.  A single tail's
sampled future costs ~0.8 ms per sample (one lane), so an uncached horizon answers in ~0.2 s at
200 samples and is then served from the cache.

Inspection interval (inspect_by): damage-tolerance practice (MIL-STD-1530C) inspects at half
the remaining time to critical; taken conservatively as half the p05 flights to critical
(model.uncertainty), null where the p05 lies beyond the horizon (no inspection is due within
half the horizon).
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import Any

import numpy as np
import pandas as pd
import torch
from sqlalchemy import delete, exists, func, select
from sqlalchemy.orm import Session, defer

from app.config import Settings
from app.errors import ConflictError
from app.services import models as model_service
from app.services.aircraft import find_aircraft
from app.services.records import stored_flights, stored_inspections
from app.services.segments import split_at_repairs
from app.tables import Aircraft, Flight, Forecast, Inspection
from model import forecast as fc
from model.hybrid import CrackGrowthModel
from model.integrate import LoadHistory
from model.records import assemble
from model.uncertainty import LaplacePosterior, probabilistic_forecast

_BATCH_AIRCRAFT = 100
# Tails x band points sampled together (the band tensor holds samples times as many floats).
_BAND_VALUES = 60_000
_EPOCH = datetime(1970, 1, 1, tzinfo=UTC)

Quantiles = tuple[float | None, float | None, float | None]  # (p05, p50, p95); None: not finite


@dataclass(frozen=True)
class TrajectoryPoint:
    date: datetime
    flights: int
    crack_length_m: float
    p05: float | None
    p50: float | None
    p95: float | None


@dataclass(frozen=True)
class Risk:
    """Sampled summary of one tail over a horizon (flights counted from its origin).

    crack_now: crack after the last flight (p05, p50, p95); prob_critical: share of samples at
    a_crit within the horizon; flights_to_critical: quantiles, None where not reached within it;
    inspect_by_flights: half the p05 flights to critical, None where beyond the horizon.
    """

    horizon_days: int
    samples: int
    crack_now: Quantiles
    prob_critical: float
    flights_to_critical: tuple[int | None, int | None, int | None]
    inspect_by_flights: int | None

    def to_json(self) -> dict[str, Any]:
        return {
            "horizon_days": self.horizon_days,
            "samples": self.samples,
            "crack_now": list(self.crack_now),
            "prob_critical": self.prob_critical,
            "flights_to_critical": list(self.flights_to_critical),
            "inspect_by_flights": self.inspect_by_flights,
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Risk:
        p05, p50, p95 = data["crack_now"]
        f05, f50, f95 = data["flights_to_critical"]
        return cls(
            int(data["horizon_days"]),
            int(data["samples"]),
            (p05, p50, p95),
            float(data["prob_critical"]),
            (f05, f50, f95),
            data["inspect_by_flights"],
        )


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
    risk: Risk
    critical_dates: tuple[datetime | None, datetime | None, datetime | None]
    inspect_by: datetime | None
    model_uncertainty: bool
    planned: bool


@dataclass(frozen=True)
class LastInspection:
    inspection_id: str
    inspected_at: datetime
    detected: bool
    crack_length_m: float | None
    repaired: bool


@dataclass(frozen=True)
class RankedTail:
    tail: str
    crack_length_m: float
    flights_to_critical: int | None
    critical_date: datetime | None
    flights_flown: int
    origin: datetime
    flights_per_day: float
    risk: Risk
    critical_dates: tuple[datetime | None, datetime | None, datetime | None]
    inspect_by: datetime | None
    last_inspection: LastInspection | None


def _ns(value: datetime) -> int:
    return int(pd.Timestamp(value).as_unit("ns").value)


def _datetime(ns: int) -> datetime:
    return _EPOCH + timedelta(microseconds=ns // 1000)


def _search_cap(flights_per_day: float, settings: Settings) -> int:
    return int(settings.critical_search_years * 365.25 * flights_per_day)


def _date_after(origin: datetime, flights: int | None, rate: float) -> datetime | None:
    if flights is None:
        return None
    return _datetime(fc.date_after_flights(_ns(origin), flights, rate))


def _tail_seed(settings: Settings, aircraft_id: int) -> int:
    """The seed of one tail's future-usage draws: the same in single forecasts and the ranking."""
    return zlib.crc32(f"{settings.forecast_seed}:{aircraft_id}".encode())


def _floats(data: bytes | None) -> np.ndarray | None:
    return None if data is None else np.frombuffer(data, dtype=np.float64)


def refresh(
    session: Session,
    version: int,
    settings: Settings,
    *,
    aircraft_ids: Sequence[int] | None = None,
    progress: Callable[[float], None] | None = None,
) -> int:
    """Recompute the cached state of these aircraft (default: all with flights) under `version`.

    Batches of aircraft march their whole histories (from their last repair) together, under
    the fitted weights and under each posterior sample, then search their time to critical
    together (model.forecast.flights_to_critical) and sample their risk over
    forecast_horizon_days.  Returns the number of tails stored.
    """
    model, posterior = model_service.load_model_and_posterior(session, version)
    if aircraft_ids is None:
        query = select(Aircraft.id).where(exists().where(Flight.aircraft_id == Aircraft.id))
        aircraft_ids = list(session.scalars(query.order_by(Aircraft.id)))
    ids = list(aircraft_ids)
    stored = 0
    for start in range(0, len(ids), _BATCH_AIRCRAFT):
        batch = ids[start : start + _BATCH_AIRCRAFT]
        stored += _refresh_batch(session, version, batch, model, posterior, settings)
        if progress is not None:
            progress(min(start + _BATCH_AIRCRAFT, len(ids)) / len(ids))
    return stored


def _crack_samples(
    model: CrackGrowthModel,
    posterior: LaplacePosterior | None,
    loads: LoadHistory,
    initial: torch.Tensor,
    settings: Settings,
) -> torch.Tensor:
    """Crack after each history (samples, aircraft) under posterior draw k (the same draws as
    probabilistic_forecast's: posterior.sample(samples, seed)); without a posterior every sample
    is the fitted model's crack."""
    samples = settings.forecast_samples
    rows = torch.arange(len(initial))
    if posterior is None:
        with torch.no_grad():
            now = model.trajectory(loads, initial)[rows, loads.lengths]
        return now.expand(samples, -1).clone()
    draws = posterior.sample(samples, settings.forecast_seed)
    out = torch.empty(samples, len(initial), dtype=torch.float64)
    stress = loads.stress_range_mpa.to(torch.float64)
    with torch.no_grad():
        for k in range(samples):
            traj = model.trajectory_with(draws[k], stress, loads.lengths, initial)
            out[k] = torch.nan_to_num(traj[rows, loads.lengths], nan=float("inf"))
    return out


def _refresh_batch(
    session: Session,
    version: int,
    aircraft_ids: list[int],
    model: CrackGrowthModel,
    posterior: LaplacePosterior | None,
    settings: Settings,
) -> int:
    flights = stored_flights(session, aircraft_ids)
    if flights.empty:
        return 0
    inspections = stored_inspections(session, aircraft_ids)
    repairs = inspections[
        inspections["repaired"].to_numpy(bool) & inspections["tail"].isin(flights["tail"])
    ]
    data = assemble(flights, repairs)
    rows = session.execute(
        select(Aircraft.tail, Aircraft.id, Aircraft.initial_crack_m).where(
            Aircraft.id.in_(aircraft_ids)
        )
    )
    by_tail = {tail: (ident, initial) for tail, ident, initial in rows}
    law = model.spec.law
    a0 = law.initial_crack_m
    initial = torch.tensor(
        [by_tail[t][1] or a0 for t in data.tails], dtype=torch.float64
    )  # (aircraft,)
    segments = split_at_repairs(data, repairs, initial)
    current = torch.from_numpy(segments.last)
    since_repair = segments.loads.select(current)  # (aircraft, flights since the last repair)
    start_crack = since_repair.initial_or(a0)
    with torch.no_grad():
        trajectory = model.trajectory(since_repair, start_crack)  # (aircraft, flights + 1)
    crack_now = trajectory[torch.arange(len(data.tails)), since_repair.lengths].tolist()
    cracks = _crack_samples(model, posterior, since_repair, start_crack, settings)
    lengths = data.loads.lengths

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
        law.critical_crack_m,
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
                crack_samples_m=cracks[:, i].numpy().tobytes(),
                recent_stress_mpa=usage[i].recent_stress_mpa.astype(np.float64).tobytes(),
                risk={},
                bands={},
            )
        )
    _fill_risk(model, posterior, records, settings.forecast_horizon_days, settings, bands=True)
    session.execute(
        delete(Forecast).where(
            Forecast.model_version == version, Forecast.aircraft_id.in_(aircraft_ids)
        )
    )
    session.add_all(records)
    session.commit()
    return len(records)


class _StackedLoads:
    """Per-tail future loads (each its own n_flights and seed) stacked, zero-padded to the longest:
    a tail's draws do not depend on which other tails are sampled with it."""

    def __init__(self, parts: Sequence[fc.FutureLoads]) -> None:
        self.parts = list(parts)
        self.n_flights = max(p.n_flights for p in self.parts)
        self.aircraft = sum(p.aircraft for p in self.parts)

    def draw(self, sample: int) -> np.ndarray:
        out = np.zeros((self.aircraft, self.n_flights))
        row = 0
        for part in self.parts:
            out[row : row + part.aircraft, : part.n_flights] = part.draw(sample)
            row += part.aircraft
        return out


def _daily_flights(horizon_days: int, rate: float) -> np.ndarray:
    return np.floor(np.arange(horizon_days + 1) * rate).astype(np.int64)


def _finite(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def _flights(value: float) -> int | None:
    return int(value) if np.isfinite(value) else None


def _sample_risk(
    model: CrackGrowthModel,
    posterior: LaplacePosterior | None,
    states: Sequence[Forecast],
    futures: Sequence[fc.FutureLoads],
    rates: Sequence[float],
    horizon_days: int,
    settings: Settings,
    *,
    bands: bool,
) -> list[tuple[Risk, dict[str, Any] | None]]:
    """Risk (and, if asked, daily bands {p05, p50, p95}: lists over days 0..horizon_days) of
    each state, sampling its future from futures[i] at rates[i] flights per day."""
    out: dict[int, tuple[Risk, dict[str, Any] | None]] = {}
    samples = settings.forecast_samples
    for chunk in _chunks(rates, horizon_days, bands):
        daily = [_daily_flights(horizon_days, rates[i]) for i in chunk]
        report = torch.from_numpy(np.unique(np.concatenate(daily))) if bands else None
        cracks = np.stack(
            [np.frombuffer(states[i].crack_samples_m or b"", np.float64) for i in chunk], axis=1
        )
        result = probabilistic_forecast(
            model,
            posterior,
            _StackedLoads([futures[i] for i in chunk]),
            crack_now_m=torch.from_numpy(cracks.copy()),
            horizon_flights=torch.tensor([futures[i].n_flights for i in chunk]),
            samples=samples,
            seed=settings.forecast_seed,
            report_flights=report if report is not None else torch.zeros(1, dtype=torch.long),
        )
        quantiles = torch.stack([result.crack_p05_m, result.crack_p50_m, result.crack_p95_m])
        ftc = torch.stack(
            [
                result.flights_to_critical_p05,
                result.flights_to_critical_p50,
                result.flights_to_critical_p95,
            ]
        ).numpy()
        band_values = quantiles.numpy()  # (3, tails, points)
        for j in range(len(chunk)):
            now = band_values[:, j, 0]
            risk = Risk(
                horizon_days=horizon_days,
                samples=samples,
                crack_now=(_finite(now[0]), _finite(now[1]), _finite(now[2])),
                prob_critical=float(result.prob_critical[j]),
                flights_to_critical=(
                    _flights(ftc[0, j]),
                    _flights(ftc[1, j]),
                    _flights(ftc[2, j]),
                ),
                inspect_by_flights=_flights(float(result.inspect_by_flights[j])),
            )
            band = None
            if report is not None:
                where = np.searchsorted(report.numpy(), daily[j])
                band = {
                    name: [_finite(v) for v in band_values[q, j, where]]
                    for q, name in enumerate(("p05", "p50", "p95"))
                }
            out[chunk[j]] = (risk, band)
    return [out[i] for i in range(len(states))]


def _chunks(rates: Sequence[float], horizon_days: int, bands: bool) -> list[list[int]]:
    """Tails sampled together: all of them without bands; with bands, tails of equal rates
    together (their daily points coincide), at most _BAND_VALUES tails x reported points."""
    if not bands:
        return [list(range(len(rates)))]
    chunks: list[list[int]] = []
    points: set[int] = set()
    for i in sorted(range(len(rates)), key=lambda i: rates[i]):
        mine = set(_daily_flights(horizon_days, rates[i]).tolist())
        union = points | mine
        if chunks and len(union) * (len(chunks[-1]) + 1) <= _BAND_VALUES:
            chunks[-1].append(i)
            points = union
        else:
            chunks.append([i])
            points = mine
    return chunks


def _recent_futures(
    states: Sequence[Forecast], horizon_days: int, settings: Settings
) -> list[fc.FutureLoads]:
    """Each tail's future resampled from its recent flights, in blocks of one day of them."""
    futures: list[fc.FutureLoads] = []
    for state in states:
        recent = np.frombuffer(state.recent_stress_mpa or b"", np.float64)
        futures.append(
            fc.ResampledLoads(
                [recent],
                fc.flights_within(horizon_days, state.flights_per_day),
                seed=_tail_seed(settings, state.aircraft_id),
                block_flights=max(1, round(state.flights_per_day)),
            )
        )
    return futures


def _fill_risk(
    model: CrackGrowthModel,
    posterior: LaplacePosterior | None,
    states: Sequence[Forecast],
    horizon_days: int,
    settings: Settings,
    *,
    bands: bool,
) -> None:
    """Sample and store the risk (and bands) of these cached states for horizon_days."""
    if not states:
        return
    futures = _recent_futures(states, horizon_days, settings)
    rates = [s.flights_per_day for s in states]
    sampled = _sample_risk(
        model, posterior, states, futures, rates, horizon_days, settings, bands=bands
    )
    key = str(horizon_days)
    for state, (risk, band) in zip(states, sampled, strict=True):
        state.risk = {**(state.risk or {}), key: risk.to_json()}
        if band is not None:
            state.bands = {**(state.bands or {}), key: {"samples": risk.samples, **band}}


def _stale(state: Forecast, settings: Settings) -> bool:
    """A row filled before uncertainty was cached, or with another sample count."""
    samples = _floats(state.crack_samples_m)
    return samples is None or len(samples) != settings.forecast_samples


def _cached(session: Session, aircraft_id: int, version: int, settings: Settings) -> Forecast:
    state = session.get(Forecast, (aircraft_id, version))
    if state is None or _stale(state, settings):
        refresh(session, version, settings, aircraft_ids=[aircraft_id])
        session.expire_all()
        state = session.get(Forecast, (aircraft_id, version))
    if state is None:
        raise ConflictError("the tail has no recorded flights: a forecast starts at the last one")
    return state


def _cached_risk(state: Forecast, horizon_days: int, settings: Settings) -> Risk | None:
    data = (state.risk or {}).get(str(horizon_days))
    if data is None or data["samples"] != settings.forecast_samples:
        return None
    return Risk.from_json(data)


@dataclass(frozen=True)
class MissionShare:
    stress_range_mpa: float
    share: float


@dataclass(frozen=True)
class Plan:
    """A planned utilization: flights per day and the mission mix."""

    flights_per_day: float
    missions: Sequence[MissionShare]

    def utilization(self) -> fc.PlannedUtilization:
        return fc.PlannedUtilization(
            self.flights_per_day,
            np.array([m.stress_range_mpa for m in self.missions], dtype=np.float64),
            np.array([m.share for m in self.missions], dtype=np.float64),
        )


def forecast_tail(
    session: Session,
    tail: str,
    *,
    horizon_days: int,
    settings: Settings,
    plan: Plan | None = None,
) -> TailForecast:
    """The tail's crack after its last flight and its projection horizon_days beyond it, with
    sampled bands, P(critical), time-to-critical quantiles and inspect-by.

    Without a plan the future repeats the tail's recent flights (point values) and resamples
    them by days (bands); the sampled summary is cached per horizon.  With a plan, future
    flights are drawn from its mission mix at its rate, point values are the p50s, nothing is
    cached.  Raises NotFoundError (unknown tail) or ConflictError (no active model, no flights).
    """
    aircraft = find_aircraft(session, tail)
    version = model_service.require_active_version(session)
    state = _cached(session, aircraft.id, version, settings)
    model, posterior = model_service.load_model_and_posterior(session, version)
    critical = model.spec.law.critical_crack_m
    key = str(horizon_days)
    if plan is None:
        rate = state.flights_per_day
        risk = _cached_risk(state, horizon_days, settings)
        band = (state.bands or {}).get(key)
        if risk is None or band is None or band.get("samples") != settings.forecast_samples:
            _fill_risk(model, posterior, [state], horizon_days, settings, bands=True)
            session.commit()
            risk = _cached_risk(state, horizon_days, settings)
            band = (state.bands or {})[key]
        assert risk is not None
        cycle = np.frombuffer(state.recent_stress_mpa or b"", np.float64)
        n = fc.flights_within(horizon_days, rate)
        future = torch.from_numpy(fc.project_loads(cycle, n)).unsqueeze(0)
        crack = torch.tensor([state.crack_length_m], dtype=torch.float64)
        point = fc.march_ahead(model, crack, future)[0].numpy()  # (n + 1,)
        flights_to_critical, critical_date = state.flights_to_critical, state.critical_date
    else:
        rate = plan.flights_per_day
        future_plan = fc.PlannedLoads(
            plan.utilization(),
            1,
            fc.flights_within(horizon_days, rate),
            seed=_tail_seed(settings, aircraft.id),
        )
        sampled = _sample_risk(
            model, posterior, [state], [future_plan], [rate], horizon_days, settings, bands=True
        )
        risk, planned_band = sampled[0]
        assert planned_band is not None
        band = planned_band
        p50 = np.array([np.inf if v is None else v for v in band["p50"]])
        point = np.empty(int(_daily_flights(horizon_days, rate)[-1]) + 1)
        point[_daily_flights(horizon_days, rate)] = p50
        flights_to_critical = risk.flights_to_critical[1]
        critical_date = _date_after(state.origin, flights_to_critical, rate)
    days, flights = fc.daily_points(point, rate, horizon_days, critical)
    points = [
        TrajectoryPoint(
            date=state.origin + timedelta(days=int(d)),
            flights=state.flights_flown + int(k),
            crack_length_m=float(point[k]),
            p05=band["p05"][int(d)],
            p50=band["p50"][int(d)],
            p95=band["p95"][int(d)],
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
        flights_per_day=rate,
        horizon_days=horizon_days,
        trajectory=points,
        flights_to_critical=flights_to_critical,
        critical_date=critical_date,
        risk=risk,
        critical_dates=_dates(state.origin, risk, rate),
        inspect_by=_date_after(state.origin, risk.inspect_by_flights, rate),
        model_uncertainty=posterior is not None,
        planned=plan is not None,
    )


def _dates(
    origin: datetime, risk: Risk, rate: float
) -> tuple[datetime | None, datetime | None, datetime | None]:
    f05, f50, f95 = risk.flights_to_critical
    return (
        _date_after(origin, f05, rate),
        _date_after(origin, f50, rate),
        _date_after(origin, f95, rate),
    )


# Most urgent first: the earliest critical date (none within the search cap: last), then the
# largest crack now.
_URGENCY = (
    Forecast.critical_date.is_(None),
    Forecast.critical_date,
    Forecast.crack_length_m.desc(),
    Aircraft.tail,
)

RANKINGS = ("risk", "crack", "due")


def _missing(session: Session, version: int, settings: Settings) -> list[int]:
    """Tails with flights whose cached state is missing or stale (see _stale)."""
    cached = exists().where(
        Forecast.aircraft_id == Aircraft.id,
        Forecast.model_version == version,
        func.length(Forecast.crack_samples_m) == 8 * settings.forecast_samples,
    )
    query = select(Aircraft.id).where(exists().where(Flight.aircraft_id == Aircraft.id), ~cached)
    return list(session.scalars(query))


def _sort_key(by: str, tail: str, risk: Risk) -> tuple[Any, ...]:
    p95 = risk.crack_now[2] if risk.crack_now[2] is not None else float("inf")
    p50 = risk.crack_now[1] if risk.crack_now[1] is not None else float("inf")
    if by == "risk":
        return (-risk.prob_critical, -p95, tail)
    if by == "crack":
        return (-p50, tail)
    due = risk.inspect_by_flights
    return (due is None, 0 if due is None else due, -risk.prob_critical, -p95, tail)


def _last_inspections(session: Session, aircraft_ids: Sequence[int]) -> dict[int, LastInspection]:
    latest = (
        select(Inspection.aircraft_id, func.max(Inspection.inspected_at).label("at"))
        .where(Inspection.aircraft_id.in_(list(aircraft_ids)))
        .group_by(Inspection.aircraft_id)
        .subquery()
    )
    query = (
        select(Inspection)
        .join(
            latest,
            (Inspection.aircraft_id == latest.c.aircraft_id)
            & (Inspection.inspected_at == latest.c.at),
        )
        .order_by(Inspection.inspection_id)
    )
    out: dict[int, LastInspection] = {}
    for i in session.scalars(query):
        out[i.aircraft_id] = LastInspection(
            i.inspection_id, i.inspected_at, i.detected, i.crack_length_m, i.repaired
        )
    return out


def ranking(
    session: Session, *, limit: int, settings: Settings, horizon_days: int, by: str = "risk"
) -> tuple[int, float, int, list[RankedTail]]:
    """Tails ordered `by` risk (P(critical within the horizon), then p95 crack now), crack (p50
    crack now, largest first) or due (earliest inspect-by; none due last, then by risk).

    Fills the cache for tails whose state is missing (new flights) and the sampled risk of the
    horizon where not cached yet.  Returns (model version, critical crack, tails ranked in all,
    the first `limit`).  Raises ValueError for an unknown `by`.
    """
    if by not in RANKINGS:
        raise ValueError(f"by must be one of {RANKINGS}, got {by!r}")
    version = model_service.require_active_version(session)
    missing = _missing(session, version, settings)
    if missing:
        refresh(session, version, settings, aircraft_ids=missing)
    model, posterior = model_service.load_model_and_posterior(session, version)
    critical = model.spec.law.critical_crack_m
    rows = list(
        session.execute(
            select(Forecast, Aircraft.tail)
            .join(Aircraft, Aircraft.id == Forecast.aircraft_id)
            .where(Forecast.model_version == version)
            .options(defer(Forecast.bands), defer(Forecast.crack_samples_m))
        )
    )
    uncached = [f for f, _ in rows if _cached_risk(f, horizon_days, settings) is None]
    if uncached:
        _fill_risk(model, posterior, uncached, horizon_days, settings, bands=False)
        session.commit()
    ranked = []
    for f, tail in rows:
        risk = _cached_risk(f, horizon_days, settings)
        assert risk is not None
        ranked.append((_sort_key(by, tail, risk), f, tail, risk))
    ranked.sort(key=lambda item: item[0])
    page = ranked[:limit]
    inspections = _last_inspections(session, [f.aircraft_id for _, f, _, _ in page])
    items = [
        RankedTail(
            tail=tail,
            crack_length_m=f.crack_length_m,
            flights_to_critical=f.flights_to_critical,
            critical_date=f.critical_date,
            flights_flown=f.flights_flown,
            origin=f.origin,
            flights_per_day=f.flights_per_day,
            risk=risk,
            critical_dates=_dates(f.origin, risk, f.flights_per_day),
            inspect_by=_date_after(f.origin, risk.inspect_by_flights, f.flights_per_day),
            last_inspection=inspections.get(f.aircraft_id),
        )
        for _, f, tail, risk in page
    ]
    return version, critical, len(ranked), items


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
