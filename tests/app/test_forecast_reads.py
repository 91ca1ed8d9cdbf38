"""What a kept forecast reads, counted in statements (no timing): a one-location aircraft's
answer served from app.services.forecasts.forecast_answers checks that it is current in one query (its
locations, their versions and row stamps: aircraft_summary.its_locations), where it made
three (that, the location notes, the row's stamp again), nine tenths of the route's time under
benchmarks/load.py.  The answers are the ones made from scratch, notes included."""

from __future__ import annotations

from datetime import timedelta
from typing import Any

from fastapi.testclient import TestClient

from tests.app.conftest import (
    START,
    add_tail,
    forget_kept_answers,
    inspect,
    later_flights,
    retrained,
    statements,
)

FORECAST = "/aircraft/MID/forecast"


def _fleet(client: TestClient) -> None:
    add_tail(client, "LOW", 40, stress=100.0)
    add_tail(client, "MID", 40, stress=150.0)
    inspect(client, "LOW", START + timedelta(days=10, hours=1), 0.0051)
    retrained(client)


def _forecast(client: TestClient, path: str = FORECAST) -> dict[str, Any]:
    answer = client.get(path)
    assert answer.status_code == 200, answer.text
    body: dict[str, Any] = answer.json()
    return body


def _of_the_request(seen: list[str]) -> list[str]:
    """The statements of the route, not the key check (kept for key_cache_seconds)."""
    return [s for s in seen if "api_keys" not in s]


def test_a_kept_forecast_reads_one_statement(client: TestClient) -> None:
    _fleet(client)
    first = _forecast(client)
    with statements(client) as seen:
        kept = _forecast(client)
    assert kept == first
    read = _of_the_request(seen)
    assert len(read) == 1, read
    assert "from locations" in read[0]
    assert kept == _from_scratch(client)


def test_a_kept_forecast_still_follows_its_row(client: TestClient) -> None:
    _fleet(client)
    before = _forecast(client)
    later_flights(client, "MID")
    after = _forecast(client)
    assert after["data_age"] != before["data_age"]
    assert after == _from_scratch(client)


def test_a_kept_forecast_still_names_a_location_without_a_model(client: TestClient) -> None:
    _fleet(client)
    assert client.put("/locations/wing", json={"stress_factor": 1.2}).status_code == 201
    first = _forecast(client)
    with statements(client) as seen:
        kept = _forecast(client)
    assert kept == first
    assert kept["unassessed_locations"] == ["wing"]
    assert [n["location"] for n in kept["location_notes"]] == ["wing"]
    assert "no active model version" in kept["location_notes"][0]["reason"]
    # the notes are read where there is one to give
    assert len(_of_the_request(seen)) == 2, seen
    assert kept == _from_scratch(client)


def _from_scratch(client: TestClient) -> dict[str, Any]:
    forget_kept_answers()
    return _forecast(client)
