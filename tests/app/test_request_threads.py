"""A forecast or a ranking takes one request thread (settings.request_threads), its route's:
its session and its horizon are made on the event loop (app.deps), so no extra hop waits for a
thread and the GIL behind an ingest's sampling; each session is still closed after it."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from datetime import timedelta
from typing import Any

import fastapi.concurrency
import fastapi.dependencies.utils
import pytest
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from tests.app.conftest import START, add_tail, inspect, retrained

# alone after the parallel run (Makefile pytest): counts what a request makes within
# key_cache_seconds
pytestmark = pytest.mark.serial


def test_a_forecast_and_a_ranking_take_their_routes_thread_alone(
    client: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    add_tail(client, "MID", 40, stress=150.0)
    inspect(client, "MID", START + timedelta(days=10, hours=1), 0.0051)
    retrained(client)
    hops: list[str] = []
    original = fastapi.dependencies.utils.run_in_threadpool

    async def counted(func: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        hops.append(getattr(func, "__qualname__", repr(func)))
        return await original(func, *args, **kwargs)

    monkeypatch.setattr(fastapi.dependencies.utils, "run_in_threadpool", counted)
    monkeypatch.setattr(fastapi.concurrency, "run_in_threadpool", counted)
    state = client.app.state  # type: ignore[attr-defined]
    made: list[Session] = []

    def recorded() -> Session:
        """Counts the sessions the routes' dependency makes on the event loop; a key read
        again after key_cache_seconds (a slow machine) makes its own on a thread, not counted."""
        session = factory()
        try:
            asyncio.get_running_loop()
        except RuntimeError:
            return session
        made.append(session)
        return session

    factory = state.session_factory
    monkeypatch.setattr(state, "session_factory", recorded)
    for path in ("/aircraft/MID/forecast", "/fleet/ranking"):
        assert client.get(path, params={"horizon_days": 30}).status_code == 200
        assert client.get(path).status_code == 200
    assert hops == []
    assert len(made) == 4
    deadline = time.monotonic() + 10  # closed after the answer, on a thread of its own
    while any(session.in_transaction() for session in made) and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not any(session.in_transaction() for session in made)
