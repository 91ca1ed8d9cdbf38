"""Annotated dependencies shared by the routers."""

from __future__ import annotations

from collections.abc import AsyncIterator
from datetime import date
from typing import Annotated

from anyio import CancelScope, CapacityLimiter, to_thread
from fastapi import Depends, Query, Request
from fastapi.exceptions import RequestValidationError
from sqlalchemy.orm import Session

from app import budget
from app.auth import page_reader, require
from app.config import Settings
from app.schemas import AsOfQuery
from app.services.audit import Actor
from app.web.chart_axis import ChartAxis


async def get_session(request: Request) -> AsyncIterator[Session]:
    """One session per request from the factory the lifespan built; rolled back unless committed.

    Made on the event loop (a session connects at its first query, on the route's thread) and
    closed on a thread with a limiter of its own (as FastAPI closes a sync dependency's): as a
    sync dependency it took a request thread (settings.request_threads) once more per request,
    a hop that waited for a thread and the GIL behind an ingest's sampling."""
    session = request.app.state.session_factory()
    try:
        yield session
    finally:
        with CancelScope(shield=True):  # a request cancelled still returns its connection
            await to_thread.run_sync(session.close, limiter=CapacityLimiter(1))


SessionDep = Annotated[Session, Depends(get_session)]


async def app_settings(request: Request) -> Settings:
    """The settings the lifespan read (get_settings, or the tests' override of it): a plain
    dependency would run get_settings on a request thread, one more hand-off per request."""
    settings: Settings = request.app.state.settings
    return settings


SettingsDep = Annotated[Settings, Depends(app_settings)]
# The caller's API key, by the least role an operation needs (app.auth): read < write < admin.
Reader = Annotated[Actor, Depends(require("read"))]
Writer = Annotated[Actor, Depends(require("write"))]
Admin = Annotated[Actor, Depends(require("admin"))]
# A person reading a page (login cookie); without one the browser is sent to the login form.
PageReader = Annotated[Actor, Depends(page_reader)]


async def bounded_as_of(settings: SettingsDep, as_of: AsOfQuery = None) -> date:
    """The request's as-of date (default today), within app.budget.as_of_window (422 outside)."""
    return budget.bounded_as_of(as_of, settings)


AsOf = Annotated[date, Depends(bounded_as_of)]


def check_horizon(value: int, settings: Settings, *, where: str = "query") -> int:
    """The one rule for a horizon: at most max_horizon_days (FLEETPINN_MAX_HORIZON_DAYS) days
    after the as-of date; more is refused (422 naming the field and the bound), never capped
    silently.  where: "query" or "body", the field's place in the request."""
    bound = settings.max_horizon_days
    if value > bound:
        raise RequestValidationError(
            [
                {
                    "type": "less_than_equal",
                    "loc": (where, "horizon_days"),
                    "msg": f"Input should be less than or equal to {bound} "
                    "(the service's FLEETPINN_MAX_HORIZON_DAYS)",
                    "input": value,
                    "ctx": {"le": bound},
                }
            ]
        )
    return value


async def horizon_days(  # async: no I/O, so no request thread (get_session says why)
    settings: SettingsDep,
    horizon_days: Annotated[
        int | None,
        Query(
            ge=1,
            description="Days after the as-of date.  Default: FLEETPINN_FORECAST_HORIZON_DAYS "
            "(365, the horizon the cache holds); at most FLEETPINN_MAX_HORIZON_DAYS (3650): "
            "more is refused with a 422.",
        ),
    ] = None,
) -> int:
    if horizon_days is None:
        return min(settings.forecast_horizon_days, settings.max_horizon_days)
    return check_horizon(horizon_days, settings)


# A route's horizon, checked against the service's bound (check_horizon).
HorizonDays = Annotated[int, Depends(horizon_days)]
# a tail chart's x axis (app.web.chart_axis)
ChartAxisQuery = Annotated[
    ChartAxis,
    Query(
        description="The x axis: `date`, or `flights` flown (coupon and component tests, whose "
        "clock is cycles: docs/real-test-data.md)."
    ),
]
