"""Per-request context: the X-Request-ID (taken from the client when sane, else generated, and
echoed), one log line per request, the latency metrics, and a JSON 500 for any error that no
handler answered (the traceback goes to the log, never to the client).

A pure ASGI middleware: the route template is read from the scope after routing (scope["route"]),
so metrics are labelled /aircraft/{tail}/forecast, not each tail's path.
"""

from __future__ import annotations

import itertools
import json
import logging
import os
import re
import secrets
import time
from typing import Any

from starlette.datastructures import MutableHeaders
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app import metrics
from app.logs import REQUEST_ID

HEADER = "X-Request-ID"
_SANE_ID = re.compile(r"^[A-Za-z0-9._:-]{1,128}$")

log = logging.getLogger("fleetpinn.request")


class _RequestIds:
    """32 hex digits unique to one request: a random prefix drawn once per process (again in a
    forked child) and a counter.  uuid4 read os.urandom on the event loop for every request, a
    system call that hands the GIL to the request threads, and the loop waited to get it back
    (12.5 % of a ranking's time in a profile under benchmarks/load.py)."""

    def __init__(self) -> None:
        self._renew()
        os.register_at_fork(after_in_child=self._renew)

    def _renew(self) -> None:
        self._prefix = secrets.token_hex(8)
        self._count = itertools.count()

    def next(self) -> str:
        return f"{self._prefix}{next(self._count) % 2**64:016x}"


_new_id = _RequestIds().next


def _incoming_id(scope: Scope) -> str | None:
    for name, value in scope.get("headers", []):
        if name == b"x-request-id":
            text = value.decode("latin-1")
            return text if _SANE_ID.match(text) else None
    return None


def route_template(scope: Scope) -> str:
    """The matched route's path template (a mount's prefix), or "unmatched"."""
    route = scope.get("route")
    path = getattr(route, "path", None)
    return str(path) if path is not None else "unmatched"


class RequestContext:
    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        request_id = _incoming_id(scope) or _new_id()
        state: dict[str, Any] = scope.setdefault("state", {})
        state["request_id"] = request_id
        status = 500
        started = False
        start = time.perf_counter()

        async def send_with_id(message: Message) -> None:
            nonlocal status, started
            if message["type"] == "http.response.start":
                status, started = message["status"], True
                MutableHeaders(scope=message).append(HEADER, request_id)
            await send(message)

        token = REQUEST_ID.set(request_id)
        try:
            await self.app(scope, receive, send_with_id)
        except Exception:
            log.exception("unhandled error in %s %s", scope["method"], scope["path"])
            if not started:
                await _internal_error(send_with_id, request_id)
        finally:
            elapsed = time.perf_counter() - start
            route = route_template(scope)
            metrics.REQUEST_SECONDS.labels(scope["method"], route).observe(elapsed)
            metrics.REQUESTS.labels(scope["method"], route, str(status)).inc()
            actor = state.get("actor")
            client = scope.get("client")
            log.info(
                "%s %s %d %.1f ms",
                scope["method"],
                scope["path"],
                status,
                elapsed * 1000,
                extra={
                    "method": scope["method"],
                    "route": route,
                    "path": scope["path"],
                    "status": status,
                    "duration_ms": round(elapsed * 1000, 3),
                    "key": None if actor is None else actor.name,
                    "client": None if client is None else client[0],
                },
            )
            REQUEST_ID.reset(token)


async def _internal_error(send: Send, request_id: str) -> None:
    body = json.dumps(
        {"detail": "internal server error; the log has the details", "request_id": request_id}
    ).encode()
    await send(
        {
            "type": "http.response.start",
            "status": 500,
            "headers": [
                (b"content-type", b"application/json"),
                (b"content-length", str(len(body)).encode()),
            ],
        }
    )
    await send({"type": "http.response.body", "body": body})
