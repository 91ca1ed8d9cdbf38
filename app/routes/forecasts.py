"""Forecasts: one tail's projection, the fleet batch job and its export."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Body, Query, Response, status

from app import budget
from app.deps import AsOf, SessionDep, SettingsDep, Writer
from app.responses import NO_MODEL, UNKNOWN_TAIL, UNKNOWN_VERSION, errors
from app.schemas import MAX_VERSION, JobAccepted, TailPath
from app.schemas_forecasts import (
    CrackAt,
    CrackBand,
    DateQuantiles,
    FlightsQuantiles,
    ForecastBatchIn,
    ForecastIn,
    ForecastOut,
    GrowthOut,
    TrajectoryPoint,
)
from app.services import export as export_service
from app.services import forecast as forecast_service
from app.services import jobs
from app.services import models as model_service
from app.services.memo import StampedMemo
from app.services.risk import Quantiles, Risk

router = APIRouter(tags=["forecasts"])


_FORECAST_RESPONSES = errors(UNKNOWN_TAIL, (409, "No active model, or the tail has no flights."))


# Encoded answers of GET forecasts (~62 KB at the default horizon), each served while its
# tail's cached row keeps the stamp it was computed from: a memo hit costs one small query
# instead of the march, 366 points built and validated, and their encoding (7.3 -> 1.5 ms of
# CPU a request, benchmarks/RESULTS.md).  Two horizons of a 600-tail fleet, ~75 MB at most.
_ANSWERS: StampedMemo[bytes] = StampedMemo(1200)


@router.get("/aircraft/{tail}/forecast", response_model=ForecastOut, responses=_FORECAST_RESPONSES)
def forecast(
    tail: TailPath,
    session: SessionDep,
    settings: SettingsDep,
    as_of: AsOf,
    horizon_days: Annotated[int, Query(ge=1, le=36_500)] = 365,
) -> Response:
    """Crack after the last recorded flight, its projection through today and the horizon."""
    horizon_days = min(horizon_days, settings.max_horizon_days)
    current = forecast_service.current_stamp(session, tail)
    key = (str(session.get_bind().engine.url), tail, horizon_days, as_of)
    body = None if current is None else _ANSWERS.get(key, (*current, settings))
    if body is None:
        result = forecast_service.forecast_tail(
            session, tail, horizon_days=horizon_days, settings=settings, as_of=as_of
        )
        body = _forecast_out(result).model_dump_json(by_alias=True).encode()
        if result.stamp is not None:
            _ANSWERS.put(key, (result.model_version, result.stamp, settings), body)
    return Response(body, media_type="application/json")


@router.post("/aircraft/{tail}/forecast", responses=_FORECAST_RESPONSES)
def forecast_planned(
    tail: TailPath,
    body: ForecastIn,
    session: SessionDep,
    settings: SettingsDep,
    as_of: AsOf,
) -> ForecastOut:
    """The forecast of GET, optionally under a planned utilization (rate and mission mix)."""
    plan = None
    if body.planned is not None:
        plan = forecast_service.Plan(
            body.planned.flights_per_day,
            [
                forecast_service.MissionShare(m.stress_range_mpa, m.share)
                for m in body.planned.missions
            ],
        )
    # A read: it stops at the time limit as a GET does (app.limits times GETs only).
    with budget.deadline(settings.request_timeout_seconds):
        result = forecast_service.forecast_tail(
            session,
            tail,
            horizon_days=min(body.horizon_days, settings.max_horizon_days),
            settings=settings,
            plan=plan,
            as_of=as_of,
        )
    return _forecast_out(result)


def _forecast_out(result: forecast_service.TailForecast) -> ForecastOut:
    risk = result.risk
    return ForecastOut(
        tail=result.tail,
        model_version=result.model_version,
        origin=result.origin,
        last_flown_at=result.last_flown_at,
        as_of=result.as_of,
        flights_flown=result.flights_flown,
        crack_length_m=result.crack_length_m,
        crack_length_band=band_out(risk.crack_now),
        crack_as_of=_crack_at(result.crack_as_of),
        crack_at_horizon=_crack_at(result.crack_at_horizon),
        critical_crack_m=result.critical_crack_m,
        flights_per_day=result.flights_per_day,
        horizon_days=result.horizon_days,
        samples=risk.samples,
        model_uncertainty=result.model_uncertainty,
        planned=result.planned,
        trajectory=[
            TrajectoryPoint(
                date=p.date,
                flights=p.flights,
                crack_length_m=p.crack_length_m,
                p05=p.p05,
                p50=p.p50,
                p95=p.p95,
            )
            for p in result.trajectory
        ],
        flights_to_critical=result.flights_to_critical,
        critical_date=result.critical_date,
        prob_critical=risk.prob_critical,
        flights_to_critical_quantiles=flights_out(risk),
        critical_date_quantiles=DateQuantiles(
            p05=result.critical_dates[0],
            p50=result.critical_dates[1],
            p95=result.critical_dates[2],
        ),
        inspect_by=result.inspect_by,
        overdue=result.overdue,
        growth=None
        if result.growth is None
        else GrowthOut(
            factor_p05=result.growth["p05"],
            factor_p50=result.growth["p50"],
            factor_p95=result.growth["p95"],
            fleet_growth_sd=result.growth["fleet_growth_sd"],
            sizing_relative_sd=result.growth["sizing_relative_sd"],
            inspection_ids=result.growth["inspection_ids"],
        ),
    )


def _crack_at(point: forecast_service.CrackAt) -> CrackAt:
    return CrackAt(
        date=point.date,
        flights=point.flights,
        crack_length_m=point.crack_length_m,
        p05=point.p05,
        p50=point.p50,
        p95=point.p95,
    )


def band_out(quantiles: Quantiles) -> CrackBand:
    p05, p50, p95 = quantiles
    return CrackBand(p05=p05, p50=p50, p95=p95)


def flights_out(risk: Risk) -> FlightsQuantiles:
    p05, p50, p95 = risk.flights_to_critical
    return FlightsQuantiles(p05=p05, p50=p50, p95=p95)


@router.post(
    "/forecasts/batch",
    status_code=status.HTTP_202_ACCEPTED,
    responses=errors(UNKNOWN_VERSION, NO_MODEL),
)
def forecast_batch(
    session: SessionDep, actor: Writer, body: Annotated[ForecastBatchIn | None, Body()] = None
) -> JobAccepted:
    """Queue a forecast of the whole fleet (stored per tail); poll GET /jobs/{job_id}."""
    params = (body or ForecastBatchIn()).model_dump(exclude_none=True)
    if "model_version" in params:
        model_service.get_version(session, params["model_version"])
    else:
        model_service.require_active_version(session)
    job = jobs.enqueue(session, "forecast-batch", params, actor=actor)
    return JobAccepted(job_id=job.id, status="queued")


@router.get(
    "/forecasts",
    responses={
        200: {
            "content": {media: {} for media in export_service.MEDIA_TYPES.values()},
            "description": "One row per tail, most urgent first.",
        },
        **errors(UNKNOWN_VERSION, NO_MODEL),
    },
    response_class=Response,
)
def export_forecasts(
    session: SessionDep,
    settings: SettingsDep,
    as_of: AsOf,
    model_version: Annotated[int | None, Query(ge=1, le=MAX_VERSION)] = None,
    format: Literal["json", "csv", "parquet"] = "json",
    horizon_days: Annotated[
        int | None, Query(ge=1, le=36_500, description="Default: the precomputed horizon.")
    ] = None,
) -> Response:
    """Every tail's forecast in the ranking's order: crack bands today and at the horizon,
    P(critical), critical dates, inspect-by, overdue, last inspection (CSV, Parquet or JSON)."""
    frame = export_service.export_frame(
        session, settings, version=model_version, horizon_days=horizon_days, as_of=as_of
    )
    return Response(
        export_service.encode(frame, format),
        media_type=export_service.MEDIA_TYPES[format],
        headers={"content-disposition": f'attachment; filename="forecasts.{format}"'},
    )
