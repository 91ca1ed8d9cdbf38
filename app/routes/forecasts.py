"""Forecasts: one tail's projection, the fleet batch job and its export."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Body, Query, Response, status

from app.config import Settings
from app.deps import HorizonDays, SessionDep, SettingsDep, Writer, check_horizon
from app.responses import NO_MODEL, UNKNOWN_TAIL, UNKNOWN_VERSION, errors
from app.schemas import MAX_VERSION, AsOfQuery, JobAccepted, TailPath
from app.schemas_forecasts import ForecastBatchIn, ForecastIn, ForecastOut
from app.services import export as export_service
from app.services import forecast as forecast_service
from app.services import jobs, reports
from app.services import models as model_service
from app.services.memo import StampedMemo

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
    horizon_days: HorizonDays,
    as_of: AsOfQuery = None,
) -> Response:
    """Crack after the last recorded flight, its projection through today and the horizon."""
    as_of = as_of or settings.today()
    current = forecast_service.current_stamp(session, tail)
    key = (str(session.get_bind().engine.url), tail, horizon_days, as_of)
    body = None if current is None else _ANSWERS.get(key, (*current, settings))
    if body is None:
        result = forecast_service.forecast_tail(
            session, tail, horizon_days=horizon_days, settings=settings, as_of=as_of
        )
        body = _forecast_out(result, settings).model_dump_json(by_alias=True).encode()
        if result.stamp is not None:
            _ANSWERS.put(key, (result.model_version, result.stamp, settings), body)
    return Response(body, media_type="application/json")


@router.post("/aircraft/{tail}/forecast", responses=_FORECAST_RESPONSES)
def forecast_planned(
    tail: TailPath,
    body: ForecastIn,
    session: SessionDep,
    settings: SettingsDep,
    as_of: AsOfQuery = None,
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
    result = forecast_service.forecast_tail(
        session,
        tail,
        horizon_days=check_horizon(body.horizon_days, settings, where="body"),
        settings=settings,
        plan=plan,
        as_of=as_of,
    )
    return _forecast_out(result, settings)


def _forecast_out(result: forecast_service.TailForecast, settings: Settings) -> ForecastOut:
    report = reports.forecast_report(result, stale_after_days=settings.stale_after_days)
    return ForecastOut.model_validate(report)


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
    horizon_days: HorizonDays,
    model_version: Annotated[int | None, Query(ge=1, le=MAX_VERSION)] = None,
    format: Literal["json", "csv", "parquet"] = "json",
    as_of: AsOfQuery = None,
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
