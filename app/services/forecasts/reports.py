"""Forecasts and the ranking as the API reports them: records named field for field as their
schemas (app.schemas_forecasts), which validate from them (`from_attributes`), so routes stay a
schema in, one service call, a schema out.

What a report adds to the service's results is the outputs' one rule for cracks past a_crit
(app.services.forecasts.tail_status): a crack length at or past a_crit is reported as null, and the tail
carries `past_critical` and `past_critical_since` instead.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from datetime import UTC, date, datetime
from typing import Any

from app.services.dates import as_of_time
from app.services.forecasts.aircraft_summary import LocationSummary
from app.services.forecasts.forecast import CrackAt, TailForecast, TrajectoryPoint
from app.services.forecasts.location_notes import LocationNote
from app.services.forecasts.residual_now import LineStrength, ResidualNow
from app.services.forecasts.risk import Dates, Quantiles, Risk
from app.services.forecasts.tail_status import DataAge, below_critical
from app.services.ranking.ranking_page import LastInspection, RankedTail


@dataclass(frozen=True)
class Band:
    p05: Any
    p50: Any
    p95: Any


def crack_band(quantiles: Quantiles, critical_crack_m: float) -> Band:
    """p05, p50, p95 of a crack, each null at or past a_crit."""
    p05, p50, p95 = (below_critical(q, critical_crack_m) for q in quantiles)
    return Band(p05, p50, p95)


def _flights(risk: Risk) -> Band:
    return Band(*risk.flights_to_critical)


def _dates(dates: Dates) -> Band:
    return Band(*dates)


def _point(point: TrajectoryPoint | CrackAt, critical: float, *, path: bool) -> dict[str, Any]:
    """A day's crack; path: a trajectory point, whose point projection stops at the first flight
    at or past a_crit (the crossing the march computed, not a held value) and is kept."""
    return {
        "date": point.date,
        "flights": point.flights,
        "crack_length_m": point.crack_length_m
        if path
        else below_critical(point.crack_length_m, critical),
        "p05": below_critical(point.p05, critical),
        "p50": below_critical(point.p50, critical),
        "p95": below_critical(point.p95, critical),
    }


@dataclass(frozen=True)
class Growth:
    factor_p05: float
    factor_p50: float
    factor_p95: float
    fleet_growth_sd: float
    sizing_relative_sd: float
    inspection_ids: list[str]


@dataclass(frozen=True)
class ForecastReport:
    tail: str
    model_version: int
    origin: datetime
    last_flown_at: datetime
    as_of: datetime
    flights_flown: int
    crack_length_m: float | None
    crack_length_band: Band
    crack_as_of: dict[str, Any]
    crack_at_horizon: dict[str, Any]
    critical_crack_m: float
    flights_per_day: float
    horizon_days: int
    samples: int
    model_uncertainty: bool
    planned: bool
    trajectory: list[dict[str, Any]]
    flights_to_critical: int | None
    critical_date: datetime | None
    prob_critical: float
    flights_to_critical_quantiles: Band
    critical_date_quantiles: Band
    inspect_by: datetime | None
    inspect_rule: str
    overdue: bool
    past_critical: bool
    past_critical_since: datetime | None
    data_age: DataAge
    stale_after_days: int
    growth: Growth | None
    # decisions per aircraft (app.services.forecasts.aircraft_summary): None for a one-location fleet
    governing_location: str | None = None
    locations: list[LocationSummary] | None = None
    # carried locations without an active version: None where there are none
    unassessed_locations: list[str] | None = None
    # the location the body's fields are of (the aircraft's answer with a summary only)
    location: str | None = None
    # carried locations left out or forecast from the fleet alone, with why: None where none
    location_notes: list[LocationNote] | None = None
    # the residual strength at the crack now (app.services.forecasts.residual_now): None where the
    # body's location cannot compute it
    residual_strength: ResidualNow | None = None
    # as_of before the forecast's origin, said in words (as_of_note): None otherwise
    as_of_note: str | None = None


def forecast_report(
    forecast: TailForecast,
    *,
    stale_after_days: int,
    inspect_rule: str,
    unassessed: Sequence[str] = (),
    notes: Sequence[LocationNote] = (),
) -> ForecastReport:
    """One tail's forecast as GET/POST /aircraft/{tail}/forecast reports it; unassessed: the
    aircraft's locations its answer cannot weigh (app.services.records.aircraft_locations.unassessed),
    notes: why, and the ones never inspected (app.services.forecasts.location_notes), each named only
    where there are some, so the answer is otherwise as before locations."""
    risk, critical = forecast.risk, forecast.critical_crack_m
    growth = forecast.growth
    return ForecastReport(
        tail=forecast.tail,
        model_version=forecast.model_version,
        origin=forecast.origin,
        last_flown_at=forecast.last_flown_at,
        as_of=forecast.as_of,
        flights_flown=forecast.flights_flown,
        crack_length_m=below_critical(forecast.crack_length_m, critical),
        crack_length_band=crack_band(risk.crack_now, critical),
        crack_as_of=_point(forecast.crack_as_of, critical, path=False),
        crack_at_horizon=_point(forecast.crack_at_horizon, critical, path=False),
        critical_crack_m=critical,
        flights_per_day=forecast.flights_per_day,
        horizon_days=forecast.horizon_days,
        samples=risk.samples,
        model_uncertainty=forecast.model_uncertainty,
        planned=forecast.planned,
        trajectory=[_point(p, critical, path=True) for p in forecast.trajectory],
        flights_to_critical=forecast.flights_to_critical,
        critical_date=forecast.critical_date,
        prob_critical=risk.prob_critical,
        flights_to_critical_quantiles=_flights(risk),
        critical_date_quantiles=_dates(forecast.critical_dates),
        inspect_by=forecast.inspect_by,
        inspect_rule=inspect_rule,
        overdue=forecast.overdue,
        past_critical=forecast.past.past_critical,
        past_critical_since=forecast.past.past_critical_since,
        data_age=forecast.data_age,
        stale_after_days=stale_after_days,
        growth=None
        if growth is None
        else Growth(
            factor_p05=growth["p05"],
            factor_p50=growth["p50"],
            factor_p95=growth["p95"],
            fleet_growth_sd=growth["fleet_growth_sd"],
            sizing_relative_sd=growth["sizing_relative_sd"],
            inspection_ids=growth["inspection_ids"],
        ),
        unassessed_locations=list(unassessed) or None,
        location_notes=list(notes) or None,
        residual_strength=_residual(forecast.residual_strength, critical),
        as_of_note=as_of_note(forecast.as_of, forecast.origin),
    )


def _residual(residual: ResidualNow | None, critical_crack_m: float) -> ResidualNow | None:
    """The residual strength with its cracks under the outputs' rule (null at or past
    a_crit); the strengths stay, computed at the cracks themselves."""
    if residual is None:
        return None
    p50, p95 = residual.p50, residual.p95
    return replace(
        residual,
        p50=replace(p50, crack_length_m=below_critical(p50.crack_length_m, critical_crack_m)),
        p95=replace(p95, crack_length_m=below_critical(p95.crack_length_m, critical_crack_m)),
    )


def as_of_note(as_of: datetime, origin: datetime) -> str | None:
    """What an as-of date before the forecast's origin gets instead of a forecast as of then:
    the projection starts at the origin (the last recorded flight, or a repair after it) from
    every record up to it, flights after as_of included, so crack_as_of is the crack at the
    origin and the horizon counts from there.  None where as_of lies on or after the origin's
    date (the forecast is as of as_of)."""
    first, start = as_of.astimezone(UTC).date(), origin.astimezone(UTC).date()
    if first >= start:
        return None
    return (
        f"as_of {first} lies before this forecast's origin {start} (the tail's last recorded "
        "flight, or a repair after it): the answer starts there from every record up to it, "
        "later ones included, not from what was known on as_of; crack_as_of is the crack at "
        "the origin and the horizon counts from the origin"
    )


@dataclass(frozen=True)
class RankingItemReport:
    rank: int
    tail: str
    crack_length_m: float | None
    crack_length_band: Band
    critical_fraction: float | None
    crack_as_of_band: Band
    crack_at_horizon_band: Band
    prob_critical: float
    inspect_by: datetime | None
    overdue: bool
    past_critical: bool
    past_critical_since: datetime | None
    data_age: DataAge
    flights_to_critical: int | None
    critical_date: datetime | None
    flights_to_critical_quantiles: Band
    critical_date_quantiles: Band
    last_inspection: LastInspection | None
    flagged_inspection_ids: list[str]
    flights_flown: int
    origin: datetime
    flights_per_day: float
    # (tail, location) rows only (app.services.ranking.location_ranking)
    location: str | None = None
    model_version: int | None = None
    critical_crack_m: float | None = None
    # where the row's location gives a limit stress
    residual_strength: LineStrength | None = None


@dataclass(frozen=True)
class RankingReport:
    model_version: int
    critical_crack_m: float
    horizon_days: int
    as_of: datetime
    by: str
    total: int
    stale_after_days: int
    items: list[RankingItemReport]


def ranking_item(rank: int, item: RankedTail, critical: float) -> RankingItemReport:
    """One ranked tail (or (tail, location) row) as the ranking reports it."""
    critical = item.critical_crack_m or critical
    crack = below_critical(item.crack_length_m, critical)
    return RankingItemReport(
        rank=rank,
        tail=item.tail,
        crack_length_m=crack,
        crack_length_band=crack_band(item.risk.crack_now, critical),
        critical_fraction=None if crack is None else crack / critical,
        crack_as_of_band=crack_band(item.risk.crack_as_of, critical),
        crack_at_horizon_band=crack_band(item.risk.crack_at_horizon, critical),
        prob_critical=item.risk.prob_critical,
        inspect_by=item.inspect_by,
        overdue=item.overdue,
        past_critical=item.past.past_critical,
        past_critical_since=item.past.past_critical_since,
        data_age=item.data_age,
        flights_to_critical=item.flights_to_critical,
        critical_date=item.critical_date,
        flights_to_critical_quantiles=_flights(item.risk),
        critical_date_quantiles=_dates(item.critical_dates),
        last_inspection=item.last_inspection,
        flagged_inspection_ids=list(item.flagged_inspection_ids),
        flights_flown=item.flights_flown,
        origin=item.origin,
        flights_per_day=item.flights_per_day,
        location=item.location,
        model_version=item.model_version,
        critical_crack_m=item.critical_crack_m,
        residual_strength=item.residual_strength,
    )


def ranking_report(
    ranked: tuple[int, float, int, list[RankedTail]],
    *,
    horizon_days: int,
    as_of: date,
    by: str,
    stale_after_days: int,
) -> RankingReport:
    """app.services.ranking.order.ranking's answer as GET /fleet/ranking reports it."""
    version, critical, total, items = ranked
    return RankingReport(
        model_version=version,
        critical_crack_m=critical,
        horizon_days=horizon_days,
        as_of=as_of_time(as_of),
        by=by,
        total=total,
        stale_after_days=stale_after_days,
        items=[ranking_item(rank, item, critical) for rank, item in enumerate(items, start=1)],
    )
