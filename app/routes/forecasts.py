"""Forecasts: one tail's projection, the fleet batch job and its export."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Body, Query, Response, status

from app.deps import SessionDep, SettingsDep
from app.schemas import ForecastBatchIn, ForecastOut, JobAccepted, TailPath, TrajectoryPoint
from app.services import forecast as forecast_service
from app.services import jobs
from app.services import models as model_service

router = APIRouter(tags=["forecasts"])


@router.get(
    "/aircraft/{tail}/forecast",
    responses={404: {"description": "Unknown tail."}, 409: {"description": "No active model."}},
)
def forecast(
    tail: TailPath,
    session: SessionDep,
    settings: SettingsDep,
    horizon_days: Annotated[int, Query(ge=1, le=36_500)] = 365,
) -> ForecastOut:
    """Crack after the last recorded flight and its projection horizon_days beyond it."""
    horizon_days = min(horizon_days, settings.max_horizon_days)
    result = forecast_service.forecast_tail(
        session, tail, horizon_days=horizon_days, settings=settings
    )
    return ForecastOut(
        tail=result.tail,
        model_version=result.model_version,
        origin=result.origin,
        flights_flown=result.flights_flown,
        crack_length_m=result.crack_length_m,
        critical_crack_m=result.critical_crack_m,
        flights_per_day=result.flights_per_day,
        horizon_days=result.horizon_days,
        trajectory=[
            TrajectoryPoint(date=p.date, flights=p.flights, crack_length_m=p.crack_length_m)
            for p in result.trajectory
        ],
        flights_to_critical=result.flights_to_critical,
        critical_date=result.critical_date,
    )


@router.post("/forecasts/batch", status_code=status.HTTP_202_ACCEPTED)
def forecast_batch(
    session: SessionDep, body: Annotated[ForecastBatchIn | None, Body()] = None
) -> JobAccepted:
    """Queue a forecast of the whole fleet (stored per tail); poll GET /jobs/{job_id}."""
    params = (body or ForecastBatchIn()).model_dump(exclude_none=True)
    if "model_version" in params:
        model_service.get_version(session, params["model_version"])
    else:
        model_service.require_active_version(session)
    job = jobs.enqueue(session, "forecast-batch", params)
    return JobAccepted(job_id=job.id, status="queued")


@router.get(
    "/forecasts",
    responses={200: {"content": {"text/csv": {}, "application/json": {}}}},
    response_model=None,
)
def export_forecasts(
    session: SessionDep,
    model_version: int | None = None,
    format: Literal["json", "csv"] = "json",
) -> Response:
    """The stored fleet forecasts of a version (default: active), most urgent first."""
    version = model_version or model_service.require_active_version(session)
    model_service.get_version(session, version)
    frame = forecast_service.export_frame(session, version)
    if format == "csv":
        return Response(frame.to_csv(index=False), media_type="text/csv")
    return Response(
        frame.to_json(orient="records", date_format="iso"), media_type="application/json"
    )
