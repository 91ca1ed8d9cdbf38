"""HTML pages for people: the fleet's risk ranking, one tail's forecast, models and jobs.

Pages render on the server (app/web templates) and read the same cached forecasts as the JSON
routes through app.web.source; errors come back as pages, never as a traceback.  A page is made
of pieces (the ranking, each location's forecast, its history, its chart, the rendering) and
checks the request's deadline (app.budget) before each, as the charts do: a page answered 503
stops within a piece instead of rendering on for a client that is gone.
"""

from __future__ import annotations

from datetime import date
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Request
from fastapi.responses import HTMLResponse

from app import budget
from app.deps import AsOf, ChartAxisQuery, SessionDep, SettingsDep
from app.errors import ConflictError, NotFoundError
from app.schemas import TailPath
from app.services.dates import as_of_time
from app.services.forecasts.residual_now import LineStrength
from app.web import catalogue, charts, location_charts, source, views
from app.web.chart_axis import CHART_AXES
from app.web.html import templates

router = APIRouter(tags=["pages"], include_in_schema=False)

# While a job runs, the models page reloads itself this often (a meta refresh, no JavaScript).
_REFRESH_SECONDS = 5
_JOBS_SHOWN = 20
# "Due within" on the fleet page, by default
_DUE_DAYS = 90


def _error_page(request: Request, status_code: int, heading: str, message: str) -> HTMLResponse:
    return templates.TemplateResponse(
        request,
        "error.html",
        {"heading": heading, "message": message, "hint": None, "tone": "warn", "nav": None},
        status_code=status_code,
    )


@router.get("/", name="fleet_page")
def fleet_page(
    request: Request,
    session: SessionDep,
    settings: SettingsDep,
    as_of: AsOf,
    sort: views.SortKey = "rank",
    order: Literal["asc", "desc"] = "asc",
    q: Annotated[str | None, Query(max_length=64, description="Tails containing this")] = None,
    show: views.Show = "all",
    due_days: Annotated[int, Query(ge=0, le=3650)] = _DUE_DAYS,
) -> HTMLResponse:
    """Every tail by risk, sortable by column, searchable by tail, filtered (server-side)."""
    horizon = min(settings.forecast_horizon_days, settings.max_horizon_days)
    budget.check()
    try:
        ranking = source.fleet_ranking(session, settings, horizon_days=horizon, as_of=as_of)
    except ConflictError:
        # A fresh install: the landing page says what to do instead of failing.
        return templates.TemplateResponse(
            request,
            "error.html",
            {
                "heading": "No forecasts yet",
                "message": "There is no active model: upload flights and inspections, then "
                "queue a retrain (POST /models/retrain).",
                "hint": "The Models & jobs page shows the retrain's progress.",
                "tone": "warn",
                "nav": "fleet",
            },
        )
    budget.check()
    now = as_of_time(ranking.as_of)
    descending = order == "desc"
    everyone = views.fleet_rows(ranking.tails, sort=sort, descending=descending)
    searched = views.search(everyone, q)
    rows = [r for r in searched if views.shows(r, show, now=now, due_days=due_days)]
    columns = views.columns_of(ranking.tails)
    pinned = _pinned(request, as_of)
    keep: dict[str, object] = {"q": q, "show": None if show == "all" else show, "as_of": pinned}
    if due_days != _DUE_DAYS:
        keep["due_days"] = due_days
    return templates.TemplateResponse(
        request,
        "fleet.html",
        {
            "nav": "fleet",
            "ranking": ranking,
            "rows": rows,
            "total": len(everyone),
            # (tail, location) rows: each location's version and a_crit, and aircraft counted
            "location_models": views.location_models(ranking.tails),
            "unassessed": source.fleet_unassessed(session),
            "aircraft": len({r.item.tail for r in everyone}),
            "columns": columns,
            "margin_column": views.MARGIN in columns,
            "sort": sort,
            "descending": descending,
            "sort_link": lambda column: views.sort_link(
                column, sort=sort, descending=descending, keep=keep
            ),
            "filter_link": lambda name: views.page_query(
                {**keep, "show": None if name == "all" else name, "sort": sort, "order": order}
            ),
            "now": now,
            "query": q or "",
            "show": show,
            "due_days": due_days,
            "as_of_param": pinned,
            "clear_link": views.page_query({"as_of": pinned}),
            "counts": views.counts(searched, now=now, due_days=due_days),
            "stale": sum(r.item.data_age.stale for r in everyone),
            "oldest_days": max(
                (r.item.data_age.days_since_last_flight for r in everyone), default=0
            ),
            "stale_after_days": settings.stale_after_days,
            # aircraft, as the other cards count (a tail's rows at several locations once)
            "likely": len({r.item.tail for r in searched if r.item.risk.prob_critical >= 0.5}),
        },
    )


def _pinned(request: Request, as_of: date) -> date | None:
    """The as-of date the page was asked for (None: today's), which its links keep."""
    return as_of if "as_of" in request.query_params else None


@router.get("/pages/aircraft/{tail}", name="aircraft_page")
def aircraft_page(
    request: Request,
    tail: TailPath,
    session: SessionDep,
    settings: SettingsDep,
    as_of: AsOf,
    horizon_days: Annotated[int | None, Query(ge=1)] = None,
    axis: ChartAxisQuery = "date",
) -> HTMLResponse:
    """One tail: forecast chart with its band and a_crit, inspections and loads; the charts
    against dates or, `axis=flights`, flights flown."""
    horizon = min(horizon_days or settings.forecast_horizon_days, settings.max_horizon_days)
    if horizon_days is not None and horizon_days > settings.max_horizon_days:
        return _error_page(
            request,
            422,
            "Horizon too long",
            f"horizon_days must be at most {settings.max_horizon_days} "
            f"(FLEETPINN_MAX_HORIZON_DAYS), got {horizon_days}.",
        )
    budget.check()
    try:
        shown_at, forecast = source.aircraft_forecast(
            session, tail, settings, horizon_days=horizon, as_of=as_of
        )
    except NotFoundError:
        return _error_page(request, 404, "Unknown tail", f"No aircraft {tail!r} is registered.")
    except ConflictError as exc:
        return _error_page(request, 409, "No forecast for this tail", str(exc))
    inspections = source.tail_inspections(session, tail)
    where = source.location_of_inspections(session, inspections)
    carried = set(source.carried_locations(session, tail))
    shown = [n for n in source.active_locations(session) if n in carried]
    named = len(shown) > 1 or shown_at != source.DEFAULT_LOCATION

    def chart(at: source.TailForecast, location: str) -> str:
        # each location's chart marks its own inspections only, and names its location
        mine = [i for i in inspections if where[i.id] == location]
        budget.check()
        history = source.tail_history(session, tail, settings, location)
        budget.check()
        return charts.inline_svg(
            charts.tail_chart(
                views.tail_series(at),
                at.critical_crack_m,
                views.inspection_marks(mine, history),
                inspect_by=at.inspect_by,
                image_format="svg",
                history=views.history_curve(history),
                as_of=at.as_of,
                location=location if named else None,
                axis=axis,
            )
        )

    others: list[dict[str, Any]] = []
    for name in shown:
        if name == shown_at:
            continue
        budget.check()
        try:
            at = source.tail_forecast(
                session, tail, settings, horizon_days=horizon, as_of=as_of, location=name
            )
        except (ConflictError, NotFoundError):  # no flights there, or not carried: no chart
            continue
        others.append({"name": name, "forecast": at, "chart": chart(at, name)})
    everyone = [(shown_at, forecast)] + [(o["name"], o["forecast"]) for o in others]
    governing = views.governing_location(everyone) if len(everyone) > 1 else None
    # as the JSON answer's lines: at the p50 crack now, where a location gives a limit stress
    strengths = {name: LineStrength.of(at.residual_strength) for name, at in everyone}
    main_chart = chart(forecast, shown_at)
    budget.check()
    return templates.TemplateResponse(
        request,
        "aircraft.html",
        {
            "nav": "fleet",
            "forecast": forecast,
            "location": shown_at if named else None,
            "governing": governing,
            "chart": main_chart,
            "other_locations": others,
            "strengths": strengths,
            "shown_at": shown_at,
            "unassessed": source.unassessed_locations(session, tail),
            "notes": source.tail_location_notes(session, tail),
            "inspections": inspections,
            # where a tail's locations are named, each inspection says which it was at
            "inspection_location": where if named else None,
            "finding": views.inspection_finding,
            "loads": source.loads_summary(session, tail),
            "overdue": forecast.overdue,
            "stale_after_days": settings.stale_after_days,
            "fleet_link": views.page_query({"as_of": _pinned(request, as_of)}),
            "axis": axis,
            "axis_links": {
                kind: views.page_query(
                    {"as_of": _pinned(request, as_of), "horizon_days": horizon_days, "axis": kind}
                )
                for kind in CHART_AXES
            },
        },
    )


@router.get("/pages/models", name="models_page")
def models_page(request: Request, session: SessionDep) -> HTMLResponse:
    """Model versions and recent jobs with their progress."""
    jobs = source.recent_jobs(session, limit=_JOBS_SHOWN)
    busy = any(job.status in ("queued", "running") for job in jobs)
    return templates.TemplateResponse(
        request,
        "models.html",
        {
            "nav": "models",
            "active": source.active_version(session),
            "active_by_location": source.active_by_location(session),
            "versions": source.model_versions(session),
            "jobs": jobs,
            "refresh_seconds": _REFRESH_SECONDS if busy else None,
        },
    )


@router.get("/pages/locations", name="locations_page")
def locations_page(request: Request, session: SessionDep, settings: SettingsDep) -> HTMLResponse:
    """The catalogue: each location's beta(a), a_crit and why, and its residual strength."""
    entries = source.catalogue(session)
    rows = catalogue.catalogue_rows(entries, settings)
    drawn = {
        row.name: charts.inline_svg(
            location_charts.location_chart(row.name, row.curves, image_format="svg")
        )
        for row in rows
        if row.curves is not None
    }
    return templates.TemplateResponse(
        request,
        "locations.html",
        {
            "nav": "locations",
            "rows": rows,
            "charts": drawn,
            "carried": source.carriers(session, entries),
        },
    )
