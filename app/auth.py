"""Who is calling: an API key in `Authorization: Bearer <key>` or `X-API-Key: <key>`, or the
pages' login cookie, checked against app.services.keys.

Roles are ordered (read < write < admin).  No key or an unknown/revoked one is a 401, a key
whose role may not do the operation a 403.  The login cookie (set by /pages/login, HttpOnly,
SameSite=Strict) counts for safe methods (GET, HEAD) only: a browser can read pages and images
with it, but a write always needs the key in a header, so another site cannot make a logged-in
browser write.  The key is checked in its own short session, so a request's own transaction
starts with its work; a key found valid is trusted for key_cache_seconds (_RecentKeys).
"""

from __future__ import annotations

import hashlib
import threading
import time
from collections import OrderedDict
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.security import APIKeyHeader, HTTPAuthorizationCredentials, HTTPBearer

from app.services import keys
from app.services.audit import Actor

COOKIE = "fleetpinn_key"
_SAFE_METHODS = ("GET", "HEAD")

bearer = HTTPBearer(
    auto_error=False,
    scheme_name="bearer",
    description="An API key (`fleetpinn keys create --role read|write|admin`).",
)
api_key_header = APIKeyHeader(
    name="X-API-Key",
    auto_error=False,
    scheme_name="apiKey",
    description="The same API key in a header of its own.",
)


class Unauthenticated(Exception):
    """No valid key (HTTP 401)."""


class Forbidden(Exception):
    """The key's role may not do this (HTTP 403)."""


class LoginRequired(Exception):
    """A page was asked for without a valid login (redirect to the login page, then back to
    next_path)."""

    def __init__(self, next_path: str) -> None:
        super().__init__(next_path)
        self.next_path = next_path


@dataclass(frozen=True)
class _Found:
    api_key_id: int
    name: str
    role: str
    until: float  # time.monotonic() after which the key is read again


class _RecentKeys:
    """Keys found valid within the last key_cache_seconds, by database and a SHA-256 of the key
    presented (the secret itself is not kept): a request with one of them reads no key row
    (a session and a query, ~0.2 ms, a tenth of a cached forecast's CPU).  So a revocation,
    made by `fleetpinn keys revoke` in another process, is refused by every API process within
    key_cache_seconds (1 s by default).  Unknown and revoked keys are never kept; at most
    `size` keys are, least recently found first out."""

    def __init__(self, size: int) -> None:
        self.size = size
        self._found: OrderedDict[tuple[str, bytes], _Found] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: tuple[str, bytes]) -> _Found | None:
        with self._lock:
            found = self._found.get(key)
            if found is None or found.until <= time.monotonic():
                return None
            return found

    def put(self, key: tuple[str, bytes], found: _Found) -> None:
        with self._lock:
            self._found[key] = found
            self._found.move_to_end(key)
            while len(self._found) > self.size:
                self._found.popitem(last=False)


_recent = _RecentKeys(1024)


def _read(request: Request, presented: str, memo_key: tuple[str, bytes]) -> _Found:
    """The live key presented, read from the database (kept in _recent); raises
    Unauthenticated."""
    state = request.app.state
    with state.session_factory() as session:
        key = keys.find_key(session, presented)
    if key is None:
        raise Unauthenticated("invalid or revoked API key")
    ttl = state.settings.key_cache_seconds
    found = _Found(key.id, key.name, key.role, time.monotonic() + ttl)
    if ttl > 0:
        _recent.put(memo_key, found)
    return found


async def _actor(request: Request, presented: str) -> Actor:
    """The caller as the key presented says; only a key not found within key_cache_seconds
    is read, on a request thread (the event loop never waits for the database)."""
    state = request.app.state
    memo_key = (str(state.engine.url), hashlib.sha256(presented.encode()).digest())
    key = _recent.get(memo_key) if state.settings.key_cache_seconds > 0 else None
    if key is None:
        key = await run_in_threadpool(_read, request, presented, memo_key)
    actor = Actor(
        name=key.name,
        role=key.role,
        api_key_id=key.api_key_id,
        request_id=getattr(request.state, "request_id", None),
    )
    request.state.actor = actor  # for the request's log line (app.middleware)
    return actor


async def authenticate(
    request: Request,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)],
    header_key: Annotated[str | None, Depends(api_key_header)],
) -> Actor:
    """The caller's key from the headers (or, for GET/HEAD, the login cookie); raises
    Unauthenticated."""
    presented = credentials.credentials if credentials is not None else header_key
    if presented is None and request.method in _SAFE_METHODS:
        presented = request.cookies.get(COOKIE)
    if presented is None:
        raise Unauthenticated(
            "missing API key: send `Authorization: Bearer <key>` or `X-API-Key: <key>`"
        )
    return await _actor(request, presented)


def require(role: str) -> Callable[[Actor], Awaitable[Actor]]:
    """A dependency that passes callers whose role allows `role`; raises Forbidden."""

    async def check(actor: Annotated[Actor, Depends(authenticate)]) -> Actor:
        return allowed(actor, role)

    check.required_role = role  # type: ignore[attr-defined]  # read by app.query_params
    return check


def allowed(actor: Actor, role: str) -> Actor:
    """actor, where its role allows `role`; raises Forbidden."""
    if not keys.allows(actor.role, role):
        raise Forbidden(f"key {actor.name!r} has role {actor.role!r}; this needs {role!r}")
    return actor


async def page_reader(request: Request) -> Actor:
    """A person reading a page: the login cookie (or a key header) with any role; raises
    LoginRequired instead of a 401 so the browser lands on the login form."""
    presented = request.headers.get("x-api-key") or request.cookies.get(COOKIE)
    authorization = request.headers.get("authorization", "")
    if authorization.lower().startswith("bearer "):
        presented = authorization[7:].strip()
    next_path = request.url.path + (f"?{request.url.query}" if request.url.query else "")
    if not presented:
        raise LoginRequired(next_path)
    try:
        return await _actor(request, presented)
    except Unauthenticated as exc:
        raise LoginRequired(next_path) from exc
