"""One tail's forecast: its crack after the last recorded flight and its projection from there,
through the as-of date (today) and horizon_days beyond it (app.services.forecasts.risk says why).

The tail's row in the forecast cache (app.services.forecasts.forecast_cache) holds where it stands; a
forecast only marches its horizon from the cached crack.  Uncertainty (model.fleet_sampling)
pairs posterior weight draw theta_k with future usage draw k, sample k starting from its own
cached crack now; the sampled summary and daily bands of a horizon are cached in the row
(app.services.forecasts.risk), so an uncached horizon answers in ~0.2 s at 200 samples and then from the
cache.  A planned utilization is sampled on every request and never cached.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from datetime import date, datetime, timedelta
from typing import Any

import numpy as np
import torch
from sqlalchemy.orm import Session

from app import budget
from app.config import Settings
from app.errors import NotFoundError
from app.services import models as model_service
from app.services.dates import as_of_time, date_after, lead_days
from app.services.forecasts import cache_rows, crack_history
from app.services.forecasts.cache_rows import Subject
from app.services.forecasts.forecast_cache import cached_state
from app.services.forecasts.residual_now import ResidualNow, residual_now
from app.services.forecasts.risk import (
    Dates,
    Risk,
    cached_band,
    cached_risk,
    decisions,
    fill_risk,
    finite,
    sample_states,
    tail_seed,
    to_band,
    to_risk,
)
from app.services.forecasts.tail_status import (
    DataAge,
    PastCritical,
    data_age,
    last_flights,
    last_inspected,
)
from app.services.records import aircraft_locations
from app.services.records import locations as location_service
from app.services.records.aircraft import find_aircraft
from model import forecast as fc
from model.posterior import daily_flights


@dataclass(frozen=True)
class TrajectoryPoint:
    date: datetime
    flights: int
    crack_length_m: float
    p05: float | None
    p50: float | None
    p95: float | None


@dataclass(frozen=True)
class CrackAt:
    """The projected crack on one day: point value (None: not finite, far past a_crit) and
    sampled quantiles."""

    date: datetime
    flights: int
    crack_length_m: float | None
    p05: float | None
    p50: float | None
    p95: float | None


@dataclass(frozen=True)
class TailForecast:
    tail: str
    model_version: int
    origin: datetime
    last_flown_at: datetime
    as_of: datetime
    flights_flown: int
    crack_length_m: float
    critical_crack_m: float
    flights_per_day: float
    horizon_days: int
    trajectory: list[TrajectoryPoint]
    flights_to_critical: int | None
    critical_date: datetime | None
    risk: Risk
    critical_dates: Dates
    inspect_by: datetime | None
    overdue: bool
    crack_as_of: CrackAt
    crack_at_horizon: CrackAt
    model_uncertainty: bool
    planned: bool
    growth: dict[str, Any] | None  # the tail's growth posterior and its evidence (model.tracking)
    data_age: DataAge
    past: PastCritical
    # The cached row's stamp (app.services.forecasts.cache_rows) where the forecast is a function of
    # that row alone (no plan, nothing sampled on the spot), else None.
    stamp: int | None = None
    # the residual strength at the crack on the as-of date (app.services.forecasts.residual_now); None
    # where the location cannot compute it
    residual_strength: ResidualNow | None = None


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
    as_of: date | None = None,
    location: str | None = None,
    trajectory: bool = True,
) -> TailForecast:
    """The tail's crack after its last flight and its projection from there through the as-of
    date (default settings.today()) and horizon_days beyond it, with sampled bands,
    P(critical by the horizon's end), time-to-critical quantiles and inspect-by.

    Without a plan the future repeats the tail's recent flights (point values) and resamples
    them by days (bands); the sampled summary is cached per (lead, horizon).  With a plan,
    future flights are drawn from its mission mix at its rate, point values are the p50s,
    nothing is cached.  location: the control point (default: the default one), forecast by
    its own active version from its own inspections and local loads.  trajectory=False: the
    decisions alone (risk, dates, inspect-by; no trajectory, point values None), as an
    aircraft's summary of its locations reads them, without marching the point values.  Raises
    NotFoundError (unknown tail or location) or ConflictError (no active model there, no
    flights).
    """
    as_of = as_of or settings.today()
    aircraft = find_aircraft(session, tail)
    location_id = location_service.location_id(session, location)
    if not aircraft_locations.carries_one(session, aircraft.id, location_id):
        raise NotFoundError(f"tail {tail!r} does not carry location {location!r}")
    version = model_service.require_active_version(session, location_id)
    subject = Subject(aircraft.id, location_id)
    state = cached_state(session, subject, version, settings)  # a snapshot
    posterior = model_service.load_posterior(session, version)
    critical = posterior.law.critical_crack_m
    lead = lead_days(state.origin, as_of)
    span = lead + horizon_days
    sampled_rate = state.flights_per_day if plan is None else plan.flights_per_day
    budget.check_span(
        fc.flights_within(span, sampled_rate), lead, horizon_days, sampled_rate, settings
    )
    stamp = None
    if plan is None:
        rate = state.flights_per_day
        risk = cached_risk(state, horizon_days, settings, as_of)
        band = cached_band(state, horizon_days, settings, as_of)
        stamp = state.stamp
        if risk is None or band is None:
            stamp = None
            fill_risk(posterior, [state], horizon_days, settings, bands=True, as_of=as_of)
            cache_rows.store_risk(session, [state], bands=True)
            session.commit()
            risk = cached_risk(state, horizon_days, settings, as_of)
            band = cached_band(state, horizon_days, settings, as_of)
        assert risk is not None and band is not None
        if trajectory:
            cycle = np.frombuffer(state.recent_stress_mpa or b"", np.float64)
            n = fc.flights_within(span, rate)
            future = torch.from_numpy(fc.project_loads(cycle, n)).unsqueeze(0)
            crack = torch.tensor([state.crack_length_m], dtype=torch.float64)
            factor = None if state.growth is None else torch.tensor([state.growth["p50"]])
            point = posterior.march_ahead(crack, future, factor)[0].numpy()  # (n + 1,)
        else:
            point = np.full(1, np.nan)  # not marched: every point value None
        flights_to_critical, critical_date = state.flights_to_critical, state.critical_date
    else:
        rate = plan.flights_per_day
        future_plan = fc.PlannedLoads(
            plan.utilization(),
            1,
            fc.flights_within(span, rate),
            seed=tail_seed(settings, aircraft.id),
        )
        (sampled,) = sample_states(
            posterior,
            [state],
            [future_plan],
            [rate],
            span,
            settings,
            bands=True,
            leads=[lead],
        )
        risk = to_risk(sampled, horizon_days, lead, settings.forecast_samples)
        band = to_band(sampled)
        days = daily_flights(span, rate)
        point = np.empty(int(days[-1]) + 1)
        point[days] = [np.inf if v is None else v for v in band["p50"]]
        flights_to_critical = risk.flights_to_critical[1]
        critical_date = date_after(state.origin, flights_to_critical, rate)

    def crack_at(day: int, quantiles: tuple[float | None, float | None, float | None]) -> CrackAt:
        k = min(int(np.floor(day * rate)), len(point) - 1)
        return CrackAt(
            date=state.origin + timedelta(days=day),
            flights=state.flights_flown + k,
            crack_length_m=finite(point[k]),
            p05=quantiles[0],
            p50=quantiles[1],
            p95=quantiles[2],
        )

    points = []
    if trajectory:
        days, flights = fc.daily_points(point, rate, span, critical)
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
    decided = decisions(state.origin, risk, rate, critical, as_of)
    past = decided.past
    if past.past_critical and state.crack_length_m >= critical:  # crossed before the origin
        history = crack_history.crack_history(
            session, tail, settings, max_points=state.flights_flown + 1, location=location
        )
        crossed = crack_history.crossed_at(history, critical)
        past = replace(past, past_critical_since=crossed or past.past_critical_since)
    last_flown_at = last_flights(session, {aircraft.id: state.origin})[aircraft.id]
    return TailForecast(
        tail=aircraft.tail,
        model_version=version,
        origin=state.origin,
        last_flown_at=last_flown_at,
        as_of=as_of_time(as_of),
        flights_flown=state.flights_flown,
        crack_length_m=state.crack_length_m,
        critical_crack_m=critical,
        flights_per_day=rate,
        horizon_days=horizon_days,
        trajectory=points,
        flights_to_critical=flights_to_critical,
        critical_date=critical_date,
        risk=risk,
        critical_dates=decided.critical_dates,
        inspect_by=decided.inspect_by,
        overdue=decided.overdue,
        crack_as_of=crack_at(lead, risk.crack_as_of),
        crack_at_horizon=crack_at(span, risk.crack_at_horizon),
        model_uncertainty=posterior.weights is not None,
        planned=plan is not None,
        growth=state.growth,
        data_age=data_age(
            last_flown_at,
            last_inspected(session, aircraft.id, location_id),
            as_of,
            stale_after_days=settings.stale_after_days,
        ),
        past=past,
        stamp=stamp,
        residual_strength=residual_now(
            location_service.location_by_id(session, location_id),
            risk.crack_as_of[1],
            risk.crack_as_of[2],
            settings,
        ),
    )


def current_stamp(
    session: Session, tail: str, location: str | None = None
) -> tuple[int, int] | None:
    """(the active version, the stamp of the tail's cached row of it), in one query; None where
    the tail, an active version or a stamped row is missing (forecast_tail says which).

    forecast_tail's answer without a plan is a function of that row, the version, the as-of
    date, the horizon and the settings: a row's stamp changes with every write of it, and
    whatever else a forecast reads (its tail's flights and repairs) changes only with its row
    (app.services.forecasts.forecast_cache).  Valid or not (read from an index, not the row): an answer
    kept under this stamp came from this very row, valid then under the settings it was kept
    with."""
    location_id = location_service.location_id(session, location)
    return cache_rows.active_stamp(session, tail, location_id)
