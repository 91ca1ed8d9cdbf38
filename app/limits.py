"""Request limits as ASGI middleware: body size (413) and the time a read may take (503).

Body size: a multipart upload may carry max_upload_bytes, any other body max_body_bytes.  A
declared Content-Length over the limit is refused before a byte is read; a body without one
(chunked) is counted as it arrives and refused when it passes the limit, before the route runs,
so nothing is stored.

Time: a GET or HEAD still running after request_timeout_seconds is answered 503.  The request
is not cancelled from outside (its route finishes, closing its own session): it carries the same
deadline (app.budget), which its sampling checks between pieces, so its work stops within one
piece of the answer and what it sends then is dropped.  Writes are never cut short here: each is
one transaction that commits whole or not at all, and its size is bounded by the body limits
instead (a file upload carries its own deadline, checked before its commit: app.routes.flights).
"""

from __future__ import annotations

import asyncio
import json

from starlette.datastructures import Headers
from starlette.exceptions import HTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app import budget
from app.config import Settings

# Cheap probes that must answer even when reads are slow.
_UNTIMED = ("/health", "/ready")


def _body_limit(settings: Settings, headers: Headers) -> tuple[int, str]:
    if headers.get("content-type", "").startswith("multipart/form-data"):
        return settings.max_upload_bytes, "max_upload_bytes"
    return settings.max_body_bytes, "max_body_bytes"


def _too_large(limit: int, name: str) -> str:
    return f"request body larger than {limit} bytes ({name}); nothing was stored"


async def _answer(send: Send, status: int, detail: str) -> None:
    body = json.dumps({"detail": detail}).encode()
    headers = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})


class RequestLimits:
    """The limits of the app's Settings (app.state.settings, set by the lifespan)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        settings: Settings | None = getattr(scope["app"].state, "settings", None)
        if scope["type"] != "http" or settings is None:
            await self.app(scope, receive, send)
            return
        headers = Headers(scope=scope)
        limit, name = _body_limit(settings, headers)
        declared = headers.get("content-length")
        if declared is not None and declared.isdigit() and int(declared) > limit:
            await _answer(send, 413, _too_large(limit, name))
            return
        received = 0

        async def counted() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    # FastAPI re-raises an HTTPException met while reading the body; its
                    # handler answers with this status and detail.
                    raise HTTPException(413, _too_large(limit, name))
            return message

        timed = scope["method"] in ("GET", "HEAD") and scope["path"] not in _UNTIMED
        if not timed:
            await self.app(scope, counted, send)
            return
        await self._timed(scope, counted, send, settings.request_timeout_seconds)

    async def _timed(self, scope: Scope, receive: Receive, send: Send, seconds: float) -> None:
        """Answer 503 after `seconds` without cancelling the request: a cancelled sync route
        would have its session closed under it while its thread still used it (500s under
        load), so it runs on to its end and what it sends then is dropped."""
        started = False
        abandoned = False

        async def tracked(message: Message) -> None:
            nonlocal started
            if abandoned:
                return
            started = started or message["type"] == "http.response.start"
            await send(message)

        async def until_abandoned() -> Message:
            if abandoned:
                return {"type": "http.disconnect"}
            return await receive()

        # The task (and the threads it hands the route to) copies this context: its deadline.
        with budget.deadline(seconds):
            task = asyncio.ensure_future(self.app(scope, until_abandoned, tracked))
        done, _ = await asyncio.wait({task}, timeout=seconds)
        if done or started:  # finished, or part of the answer is out: let it end as it does
            await task
            return
        abandoned = True
        _orphans.add(task)
        task.add_done_callback(_orphans.discard)
        await _answer(send, 503, budget.timed_out_message(seconds))


# Requests answered 503 that still run (a reference keeps each task alive until it ends).
_orphans: set[asyncio.Future[None]] = set()
