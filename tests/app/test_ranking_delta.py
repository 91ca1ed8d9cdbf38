"""A kept fleet order goes stale when rows change; it is brought up to date from the changed
rows alone (app.services.ranking.ranking_delta), and the answer equals one made from scratch whatever
the change: an ingest, a repair, an inspection, a corrected or deleted record, a new tail, a
deleted tail, another version.  Tomorrow's risk, which an ingest leaves to the worker, is
stored without a new stamp, so no kept answer is made anew for it."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from datetime import timedelta
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select

from app.config import Settings
from app.services.dates import days_ahead
from app.services.forecasts.risk import cached_risk
from app.services.ranking import location_ranking
from app.services.ranking import order as ranking
from app.tables import Aircraft, Forecast
from app.worker import Worker
from tests.app.conftest import (
    START,
    add_tail,
    flights,
    forget_kept_answers,
    inspect,
    later_flights,
    repair,
    retrained,
)
from tests.app.snapshots import copied_for_each_test, served_settings

TAILS = {"LOW": 100.0, "MID": 150.0, "HIGH": 200.0, "TOP": 220.0}


def _store_fleet(client: TestClient) -> None:
    """Four tails of 40 flights at their own stress (LOW inspected), the physics active."""
    for tail, stress in TAILS.items():
        add_tail(client, tail, 40, stress=stress)
    inspect(client, "LOW", START + timedelta(days=10, hours=1), 0.0051)
    retrained(client)


stored_database, fleet = copied_for_each_test("fleet", _store_fleet)


@pytest.fixture
def settings(fleet: TestClient) -> Settings:
    """The settings the fleet's copy is served with."""
    return served_settings(fleet)


def _ranking(client: TestClient, **params: Any) -> bytes:
    answer = client.get("/fleet/ranking", params=params)
    assert answer.status_code == 200, answer.text
    return answer.content


def _from_scratch(client: TestClient, **params: Any) -> bytes:
    forget_kept_answers()
    return _ranking(client, **params)


def _ok(answer: Any) -> None:
    assert answer.status_code in (200, 201), answer.text


CHANGES: dict[str, Callable[[TestClient], object]] = {
    "new flights": lambda c: later_flights(c, "MID"),
    "repair": lambda c: repair(c, "MID"),
    "new inspection": lambda c: inspect(c, "HIGH", START + timedelta(days=9), 0.0056),
    "corrected flight": lambda c: _ok(
        c.patch("/aircraft/MID/flights/F0040", json={"stress_range_mpa": 300.0})
    ),
    "deleted flight": lambda c: _ok(c.delete("/aircraft/MID/flights/F0040")),
    "new tail": lambda c: add_tail(c, "NEW", 40, stress=260.0),
    "deleted tail": lambda c: _ok(c.delete("/aircraft/TOP")),
    "new version": retrained,
}


@pytest.mark.parametrize("by", ["risk", "crack"])
@pytest.mark.parametrize("change", sorted(CHANGES))
def test_a_ranking_brought_up_to_date_is_the_one_made_from_scratch(
    fleet: TestClient, change: str, by: str
) -> None:
    before = _ranking(fleet, by=by)
    assert _ranking(fleet, by=by) == before  # kept
    CHANGES[change](fleet)
    after = _ranking(fleet, by=by)
    assert after == _from_scratch(fleet, by=by)
    assert _ranking(fleet, by=by) == after


@pytest.fixture
def orders(monkeypatch: pytest.MonkeyPatch, settings: Any) -> Iterator[list[int]]:
    """The versions ranking._order reads all rows of as of today or tomorrow, in order, for
    anyone but the app's own cache thread: it orders tomorrow first whenever its first poll
    comes, which on a loaded machine was after a test had cleared the list (CI, 2026-11-27)."""
    made: list[int] = []
    order = ranking._order
    days = days_ahead(settings)

    def counted(session: Any, version: int, *args: Any) -> Any:
        if args[-1] in days and threading.current_thread().name != "fleetpinn-cache":
            made.append(version)
        return order(session, version, *args)

    monkeypatch.setattr(ranking, "_order", counted)
    yield made


def test_an_ingest_rereads_only_its_tails_row(fleet: TestClient, orders: list[int]) -> None:
    """After an ingest the ranking reads no version's rows anew; after two ingests too."""
    _ranking(fleet)
    orders.clear()
    later_flights(fleet, "MID")
    after = _ranking(fleet)
    _ok(fleet.post("/aircraft/HIGH/flights", json=flights(43, stress=250.0)[40:]))
    again = _ranking(fleet)
    assert orders == []
    assert again != after and again == _from_scratch(fleet)


def _stamps_and_tomorrow(client: TestClient, settings: Any) -> tuple[dict[str, int], list[bool]]:
    factory = client.app.state.session_factory  # type: ignore[attr-defined]
    _, tomorrow = days_ahead(settings)
    with factory() as session:
        rows = session.execute(select(Aircraft.tail, Forecast).join(Forecast)).all()
        stamps = {tail: row.stamp for tail, row in rows}
        ahead = [
            cached_risk(row, settings.forecast_horizon_days, settings, tomorrow) is not None
            for _, row in rows
        ]
    return stamps, ahead


def test_rankings_that_meet_after_a_change_make_the_answer_once(
    fleet: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Rankings that arrive while one request thread makes the answer anew after a change
    wait for its answer instead of each making it (ranking_answers.encoded_ranking)."""
    before = _ranking(fleet)
    later_flights(fleet, "MID")
    made: list[int] = []
    original = location_ranking.ranking

    def slow(*args: Any, **kwargs: Any) -> Any:
        made.append(1)
        time.sleep(0.3)  # the other rankings arrive meanwhile
        return original(*args, **kwargs)

    monkeypatch.setattr(location_ranking, "ranking", slow)
    with ThreadPoolExecutor(4) as pool:
        bodies = set(pool.map(lambda _: _ranking(fleet), range(4)))
    assert len(made) == 1
    assert len(bodies) == 1 and before not in bodies and bodies == {_from_scratch(fleet)}


def test_tomorrows_risk_is_the_workers_and_keeps_the_stamp(
    fleet: TestClient, settings: Any, orders: list[int]
) -> None:
    """An ingest stores today's risk alone; the worker's cache step stores tomorrow's for the
    tail ingested without changing its row's stamp, so the kept ranking is served on."""
    factory = fleet.app.state.session_factory  # type: ignore[attr-defined]
    worker = Worker(factory, settings, "test")
    worker.warm_today()
    _, tomorrow = days_ahead(settings)
    today = _ranking(fleet)
    _ = _ranking(fleet, as_of=tomorrow.isoformat())
    later_flights(fleet, "MID")
    stamps, _ = _stamps_and_tomorrow(fleet, settings)
    after = _ranking(fleet)
    assert after != today
    worker.warm_today()
    stamps_after, ahead = _stamps_and_tomorrow(fleet, settings)
    assert stamps_after == stamps and all(ahead)
    orders.clear()
    assert _ranking(fleet) == after
    next_day = _ranking(fleet, as_of=tomorrow.isoformat())
    assert orders == []
    assert next_day == _from_scratch(fleet, as_of=tomorrow.isoformat())
