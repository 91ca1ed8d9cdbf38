"""The application: lifespan (logs, migrations, engine, worker), routers, middleware and error
handlers.  Every API router needs at least a read key (app.auth); health, readiness, metrics,
the API docs and the login form are open; the pages need the login cookie."""

from __future__ import annotations

import gc
from collections.abc import AsyncIterator, Sequence
from contextlib import asynccontextmanager
from typing import Any
from urllib.parse import quote

from anyio import to_thread
from fastapi import Depends, FastAPI, Request, status
from fastapi.encoders import jsonable_encoder
from fastapi.exception_handlers import http_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, RedirectResponse, Response
from starlette.exceptions import HTTPException
from starlette.routing import Match

from app import budget, logs, migrate, openapi_bounds
from app.auth import Forbidden, LoginRequired, Unauthenticated, page_reader, require
from app.config import Settings, get_settings
from app.db import make_engine, make_session_factory
from app.errors import ConflictError, NotFoundError, QueueFull
from app.limits import RequestLimits
from app.middleware import RequestContext
from app.query_params import one_value_each
from app.responses import COMMON
from app.routes import (
    aircraft,
    audit,
    docs,
    fleet,
    flights,
    forecasts,
    health,
    images,
    inspections,
    jobs,
    locations,
    login,
    metrics,
    models,
    pages,
)
from app.schema_types import echoed, encodable
from app.services.forecasts.answers_ahead import AnswersAhead
from app.services.jobs.queue import QUEUE_LIMIT
from app.web import html
from app.worker import Worker
from model.records import RecordError
from model.runtime import configure_threads, warm_up


def _settings(app: FastAPI) -> Settings:
    # Tests override get_settings through dependency_overrides; honour that here too.
    provider = app.dependency_overrides.get(get_settings, get_settings)
    settings: Settings = provider()
    return settings


@asynccontextmanager
async def lifespan(app: FastAPI) -> AsyncIterator[None]:
    settings = _settings(app)
    logs.configure(settings.log_format, settings.log_level)
    if settings.migrate_on_start:
        migrate.upgrade(settings.database_url)
    # Per process (uvicorn --workers spawns fresh ones): one torch thread (model.runtime says
    # why; two per process stalled requests for seconds beside a busy core) and the march
    # loaded before the first request needs it (~0.5 s from numba's cache).
    configure_threads()
    warm_up()
    # The start-up heap (torch, numba, SQLAlchemy: ~0.4 M objects) out of the garbage
    # collector's sight: a full collection walks it with the GIL held (0.16 s idle), stalling
    # every request of the process.
    gc.collect()
    gc.freeze()
    to_thread.current_default_thread_limiter().total_tokens = settings.request_threads
    engine = make_engine(settings.database_url)
    app.state.settings = settings
    app.state.engine = engine
    app.state.session_factory = make_session_factory(
        engine, info={QUEUE_LIMIT: settings.max_queued_jobs}
    )
    worker = Worker(app.state.session_factory, settings, name="api")
    if settings.run_worker:
        worker.start()
    # below the requests, as the worker's cache thread (app.worker)
    ahead = AnswersAhead(
        app.state.session_factory, settings, forecasts.encoded_body, nice=settings.worker_nice // 2
    )
    if settings.answers_ahead:
        ahead.start()
    app.state.answers_ahead = ahead
    try:
        yield
    finally:
        ahead.stop()
        worker.stop()
        engine.dispose()


async def _record_error(_: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RecordError)
    body = {"detail": str(exc), "source": exc.source, "row": exc.row, "column": exc.column}
    return JSONResponse({**body, "reason": exc.reason}, status.HTTP_422_UNPROCESSABLE_CONTENT)


async def _not_found(_: Request, exc: Exception) -> JSONResponse:
    return JSONResponse({"detail": str(exc.args[0]) if exc.args else "not found"}, 404)


async def _conflict(_: Request, exc: Exception) -> JSONResponse:
    return JSONResponse({"detail": str(exc)}, status.HTTP_409_CONFLICT)


async def _unauthenticated(_: Request, exc: Exception) -> JSONResponse:
    headers = {"WWW-Authenticate": "Bearer"}
    return JSONResponse({"detail": str(exc)}, status.HTTP_401_UNAUTHORIZED, headers=headers)


async def _forbidden(_: Request, exc: Exception) -> JSONResponse:
    return JSONResponse({"detail": str(exc)}, status.HTTP_403_FORBIDDEN)


async def _login_required(_: Request, exc: Exception) -> RedirectResponse:
    assert isinstance(exc, LoginRequired)
    return RedirectResponse(f"/pages/login?next={quote(exc.next_path)}", status_code=303)


# A body of many bad rows answers with the first ones' errors (each error is ~200 bytes).
_MAX_ERRORS = 100


def _quoted_short(errors: Sequence[Any]) -> list[Any]:
    """The first _MAX_ERRORS errors, each quoting a prefix of its input (schema_types.echoed)."""
    return [
        {**error, "input": echoed(error["input"])} if "input" in error else error
        for error in list(errors)[:_MAX_ERRORS]
    ]


async def _invalid_request(_: Request, exc: Exception) -> JSONResponse:
    """FastAPI's error list, plus row (1-based), column and reason of the first bad body row."""
    assert isinstance(exc, RequestValidationError)
    errors = encodable(jsonable_encoder(_quoted_short(exc.errors())))
    body: dict[str, object] = {"detail": errors}
    first = errors[0] if errors else None
    if first and first.get("type") == "json_invalid":
        # loc's number is a character offset into the body here, not a row
        loc = list(first.get("loc", []))
        at = f" at character {loc[1] + 1}" if len(loc) >= 2 and isinstance(loc[1], int) else ""
        problem = (first.get("ctx") or {}).get("error") or first.get("msg")
        body["reason"] = f"the body is not valid JSON{at}: {problem}"
    elif first:
        loc = list(first.get("loc", []))
        if len(loc) >= 2 and loc[0] == "body" and isinstance(loc[1], int):
            body.update(row=loc[1] + 1, column=loc[2] if len(loc) > 2 else None)
        body["reason"] = first.get("msg")
    return JSONResponse(body, status.HTTP_422_UNPROCESSABLE_CONTENT)


async def _out_of_bounds(_: Request, exc: Exception) -> JSONResponse:
    """An input over the request budget (app.budget): the shape of a request that does not fit
    its schema."""
    assert isinstance(exc, budget.OutOfBounds)
    errors = encodable(jsonable_encoder(_quoted_short(exc.errors())))
    body = {"detail": errors, "reason": exc.message}
    return JSONResponse(body, status.HTTP_422_UNPROCESSABLE_CONTENT)


async def _queue_full(_: Request, exc: Exception) -> JSONResponse:
    headers = {"Retry-After": "60"}
    return JSONResponse({"detail": str(exc)}, status.HTTP_429_TOO_MANY_REQUESTS, headers=headers)


async def _deadline(_: Request, exc: Exception) -> JSONResponse:
    return JSONResponse({"detail": str(exc)}, status.HTTP_503_SERVICE_UNAVAILABLE)


_METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS")


async def _http_error(request: Request, exc: Exception) -> Response:
    """FastAPI's answer, except that a 405 names in `Allow` every method of every route at
    the path (Starlette names only the first route's, e.g. GET of /aircraft/{tail}, not PUT)."""
    assert isinstance(exc, HTTPException)
    if exc.status_code != status.HTTP_405_METHOD_NOT_ALLOWED:
        return await http_exception_handler(request, exc)
    allowed = [
        method
        for method in _METHODS
        if any(
            route.matches({**request.scope, "method": method})[0] == Match.FULL
            for route in request.app.router.routes
        )
    ]
    headers = {"Allow": ", ".join(allowed)}
    return JSONResponse({"detail": exc.detail}, exc.status_code, headers=headers)


def create_app() -> FastAPI:
    app = FastAPI(
        title="fleetpinn",
        summary="Fleet fatigue-crack prognosis with hybrid physics-informed networks.",
        version="0.1.0",
        lifespan=lifespan,
        # Served by app.routes.docs from the package's own assets (no CDN).
        docs_url=None,
        redoc_url=None,
    )
    # a one-value query parameter sent twice is a 422, on every route (app.query_params), after
    # the key is checked: an app-wide dependency ran first and answered 422 for a missing key
    once = Depends(one_value_each)
    for router in (health.router, metrics.router, docs.router, login.router):
        app.include_router(router, dependencies=[once])
    for router in (
        aircraft.router,
        locations.router,
        flights.router,
        inspections.router,
        models.router,
        jobs.router,
        forecasts.router,
        fleet.router,
        images.router,
        audit.router,
    ):
        # Writes and admin operations ask for their role on top (app.deps.Writer, Admin).
        app.include_router(router, dependencies=[Depends(require("read")), once], responses=COMMON)
    app.include_router(pages.router, dependencies=[Depends(page_reader), once])
    app.mount("/static", html.static_files(), name=html.STATIC_NAME)
    app.mount(docs.ASSETS_PATH, docs.assets(), name=docs.ASSETS_NAME)
    app.add_exception_handler(HTTPException, _http_error)
    app.add_exception_handler(RecordError, _record_error)
    app.add_exception_handler(NotFoundError, _not_found)
    app.add_exception_handler(ConflictError, _conflict)
    app.add_exception_handler(QueueFull, _queue_full)
    app.add_exception_handler(RequestValidationError, _invalid_request)
    app.add_exception_handler(budget.OutOfBounds, _out_of_bounds)
    app.add_exception_handler(budget.DeadlineExceeded, _deadline)
    app.add_exception_handler(Unauthenticated, _unauthenticated)
    app.add_exception_handler(Forbidden, _forbidden)
    app.add_exception_handler(LoginRequired, _login_required)
    # The last added is the outermost: the request's log line and metrics see what the client
    # got, the limits' 413 and 503 included (inside them they logged the abandoned route's 200).
    app.add_middleware(RequestLimits)
    app.add_middleware(RequestContext)
    _openapi_with_settings_bounds(app)
    return app


def _openapi_with_settings_bounds(app: FastAPI) -> None:
    """The OpenAPI schema, built once, states the bounds of this process's settings."""
    build = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            app.openapi_schema = openapi_bounds.state_bounds(build(), _settings(app))
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]


app = create_app()
