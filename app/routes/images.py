"""Forecast charts as images for other tools (reports, dashboards): SVG or PNG.

A chart is made of pieces (each tail's forecast, its history, the drawing), and the request's
deadline (app.budget) is checked before each, as the ranking's sampling checks it: a chart
answered 503 stops within a piece instead of drawing on for a client that is gone (issue 42:
an SVG ran 109 s past its 503), and so does one whose thread started after its deadline."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query, Response

from app import budget
from app.deps import AsOf, ChartAxisQuery, HorizonDays, SessionDep, SettingsDep
from app.responses import NO_MODEL, UNKNOWN_TAIL, errors
from app.schemas import TailPath
from app.web import charts, source, views

router = APIRouter(tags=["images"])

_IMAGE: dict[int | str, dict[str, Any]] = {
    200: {"content": {"image/svg+xml": {}, "image/png": {}}, "description": "The chart."},
}
_TAIL_ERRORS: dict[int | str, dict[str, Any]] = {
    **_IMAGE,
    **errors(UNKNOWN_TAIL, (409, "No active model, or the tail has no flights.")),
}


def _image(content: bytes, image_format: charts.ImageFormat) -> Response:
    return Response(content, media_type=charts.MEDIA_TYPES[image_format])


@router.get(
    "/aircraft/{tail}/forecast.{image_format}",
    name="forecast_image",
    response_class=Response,
    responses=_TAIL_ERRORS,
)
def forecast_image(
    tail: TailPath,
    image_format: charts.ImageFormat,
    session: SessionDep,
    settings: SettingsDep,
    as_of: AsOf,
    horizon_days: HorizonDays,
    axis: ChartAxisQuery = "date",
) -> Response:
    """The tail's forecast chart: projection, p05-p95 band, a_crit, inspections, inspect-by; of
    the default location, or of the governing one where the tail carries no default with a
    model (the title names it); against dates or, `axis=flights`, flights flown."""
    budget.check()
    location, forecast = source.aircraft_forecast(
        session, tail, settings, horizon_days=horizon_days, as_of=as_of
    )
    budget.check()
    inspections = source.tail_inspections(session, tail)
    where = source.location_of_inspections(session, inspections)
    history = source.tail_history(session, tail, settings, location)
    budget.check()
    chart = charts.tail_chart(
        views.tail_series(forecast),
        forecast.critical_crack_m,
        views.inspection_marks([i for i in inspections if where[i.id] == location], history),
        inspect_by=forecast.inspect_by,
        image_format=image_format,
        history=views.history_curve(history),
        as_of=forecast.as_of,
        location=None if location == source.DEFAULT_LOCATION else location,
        axis=axis,
    )
    return _image(chart, image_format)


@router.get(
    "/fleet/ranking.{image_format}",
    name="ranking_image",
    response_class=Response,
    responses={**_IMAGE, **errors(NO_MODEL)},
)
def ranking_image(
    image_format: charts.ImageFormat,
    session: SessionDep,
    settings: SettingsDep,
    as_of: AsOf,
    horizon_days: HorizonDays,
    top: Annotated[int, Query(ge=1, le=20)] = 10,
) -> Response:
    """The `top` tails by risk: each one's p50 crack and p05-p95 band over the horizon."""
    budget.check()
    tails = source.top_tails(session, settings, top=top, horizon_days=horizon_days, as_of=as_of)
    forecasts = []
    for t in tails:
        budget.check()
        forecasts.append(
            source.aircraft_forecast(session, t, settings, horizon_days=horizon_days, as_of=as_of)[
                1
            ]
        )
    budget.check()
    critical = forecasts[0].critical_crack_m if forecasts else settings.critical_crack_m
    series = [views.tail_series(f) for f in forecasts]
    return _image(charts.ranking_chart(series, critical, image_format=image_format), image_format)
