"""Forecasts: one tail's projection, the fleet batch job and its export."""

from __future__ import annotations

from dataclasses import replace
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Body, Query, Response, status

from app import budget
from app.deps import AsOf, HorizonDays, SessionDep, SettingsDep, Writer, check_horizon
from app.responses import NO_MODEL, QUEUE_FULL, UNKNOWN_TAIL, UNKNOWN_VERSION, errors
from app.schemas import MAX_VERSION, JobAccepted, TailPath
from app.schemas_forecasts import ForecastBatchIn, ForecastIn, ForecastOut
from app.schemas_locations import LocationPath
from app.services import models as model_service
from app.services.forecasts import aircraft_summary, forecast_answers, reports, risk
from app.services.forecasts import forecast as forecast_service
from app.services.jobs import queue as jobs
from app.services.ranking import export as export_service
from app.services.records import aircraft_locations

router = APIRouter(tags=["forecasts"])


_FORECAST_RESPONSES = errors(UNKNOWN_TAIL, (409, "No active model, or the tail has no flights."))


@router.get("/aircraft/{tail}/forecast", response_model=ForecastOut, responses=_FORECAST_RESPONSES)
def forecast(
    tail: TailPath,
    session: SessionDep,
    settings: SettingsDep,
    horizon_days: HorizonDays,
    as_of: AsOf,
) -> Response:
    """Crack after the last recorded flight, its projection through today and the horizon."""
    body = forecast_answers.encoded_forecast(
        session,
        tail,
        horizon_days=horizon_days,
        as_of=as_of,
        settings=settings,
        encode=encoded_body,
    )
    return Response(body, media_type="application/json")


@router.get(
    "/aircraft/{tail}/locations/{name}/forecast",
    response_model=ForecastOut,
    responses=errors(
        (404, "Unknown tail or location."),
        (409, "No active model at the location, or the tail has no flights."),
    ),
)
def location_forecast(
    tail: TailPath,
    name: LocationPath,
    session: SessionDep,
    settings: SettingsDep,
    horizon_days: HorizonDays,
    as_of: AsOf,
) -> Response:
    """One control point's forecast, in full: its own model, inspections and local loads."""
    body = forecast_answers.encoded_forecast(
        session,
        tail,
        horizon_days=horizon_days,
        as_of=as_of,
        settings=settings,
        encode=encoded_body,
        location=name,
    )
    return Response(body, media_type="application/json")


def encoded_body(report: reports.ForecastReport) -> bytes:
    """A forecast's answer as GET sends it (app.services.forecasts.answers_ahead makes them too)."""
    # the aircraft's fields only where they say something: a one-location fleet's answer
    # stays byte for byte what it was, and so does a location without a residual strength
    # (a constant factor) or a line without a limit stress
    optional = ("location", "unassessed_locations", "location_notes", "as_of_note")
    absent: dict[str, Any] = {name: True for name in optional if getattr(report, name) is None}
    if report.residual_strength is None:
        absent["residual_strength"] = True
    if report.locations is None:
        absent.update(governing_location=True, locations=True)
    else:
        plain = [k for k, line in enumerate(report.locations) if line.residual_strength is None]
        if plain:
            absent["locations"] = {k: {"residual_strength"} for k in plain}
    return (
        ForecastOut.model_validate(report).model_dump_json(by_alias=True, exclude=absent).encode()
    )


@router.post("/aircraft/{tail}/forecast", response_model=ForecastOut, responses=_FORECAST_RESPONSES)
def forecast_planned(
    tail: TailPath,
    body: ForecastIn,
    session: SessionDep,
    settings: SettingsDep,
    as_of: AsOf,
) -> Response:
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
    horizon_days = check_horizon(body.horizon_days, settings, where="body")
    with budget.deadline(settings.request_timeout_seconds):
        # the default location's, or the governing one's where the tail has no default model
        location = aircraft_summary.aircraft_location(
            session, tail, horizon_days=horizon_days, as_of=as_of, settings=settings
        )
        result = forecast_service.forecast_tail(
            session,
            tail,
            horizon_days=horizon_days,
            settings=settings,
            plan=plan,
            as_of=as_of,
            location=location,
        )
    report = reports.forecast_report(
        result,
        stale_after_days=settings.stale_after_days,
        inspect_rule=risk.inspect_rule(settings),
        unassessed=aircraft_locations.unassessed(session, tail),
    )
    if location is not None:
        report = replace(report, location=location)
    return Response(encoded_body(report), media_type="application/json")


@router.post(
    "/forecasts/batch",
    status_code=status.HTTP_202_ACCEPTED,
    responses=errors(UNKNOWN_VERSION, NO_MODEL, QUEUE_FULL),
)
def forecast_batch(
    session: SessionDep, actor: Writer, body: Annotated[ForecastBatchIn | None, Body()] = None
) -> JobAccepted:
    """Queue a forecast of the whole fleet (stored per tail); poll GET /jobs/{job_id}."""
    params = (body or ForecastBatchIn()).model_dump(exclude_none=True)
    if "model_version" in params:
        model_service.get_version(session, params["model_version"])
    elif not model_service.active_versions(session):  # none at any location
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
    as_of: AsOf,
    model_version: Annotated[int | None, Query(ge=1, le=MAX_VERSION)] = None,
    format: Literal["json", "csv", "parquet"] = "json",
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
