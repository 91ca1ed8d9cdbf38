"""A record time's pattern in the OpenAPI schema: schemathesis drew flown_at
2024-01-01T24:00:00Z (a valid RFC 3339 date-time, with the date inside the window) and the
server refused it; the pattern now states the time of day the server reads as well."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from tests.app.conftest import serving, settings_in

# Valid RFC 3339 (or nearly) that the server refuses, then times it takes; a time without an
# offset is taken too, but `format: date-time` already calls it invalid.
REFUSED = [
    "2024-01-01T24:00:00Z",
    "2024-01-01T23:60:00Z",
    "2024-01-01T23:59:60Z",
    "2024-01-01t06:00:00z",
    "2024-01-01T06:00:00+24:00",
    "2024-01-01T06:00:00.Z",
]
TAKEN = [
    "2024-01-01T23:59:59Z",
    "2024-01-01T06:00:00.123456789Z",
    "2024-01-01T06:00:00,5Z",
    "2023-12-31T06:00:00-00:00",
    "2023-12-31T06:00:00+0100",
]
TIMES = REFUSED + TAKEN


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    with serving(settings_in(Path(tmp_path_factory.mktemp("times")))) as test_client:
        assert test_client.put("/aircraft/H1").status_code == 201
        yield test_client


def _stated(client: TestClient, component: str, field: str) -> re.Pattern[str]:
    declared = client.get("/openapi.json").json()["components"]["schemas"][component]
    alternatives = declared["properties"][field].get("anyOf", [declared["properties"][field]])
    (pattern,) = [a["pattern"] for a in alternatives if a.get("format") == "date-time"]
    return re.compile(pattern)


def test_a_flight_time_is_taken_exactly_where_its_pattern_says(client: TestClient) -> None:
    stated = _stated(client, "FlightIn", "flown_at")
    for n, flown_at in enumerate(TIMES):
        body = [{"flight_id": f"T{n}", "flown_at": flown_at, "stress_range_mpa": 100.0}]
        answer = client.post("/aircraft/H1/flights", json=body)
        assert answer.status_code in (201, 422), answer.text
        assert (answer.status_code == 201) == bool(stated.search(flown_at)), (flown_at, answer.text)
    assert client.get("/aircraft/H1").json()["flight_count"] == len(TAKEN)


def test_an_inspection_time_is_taken_exactly_where_its_pattern_says(client: TestClient) -> None:
    stated = _stated(client, "InspectionIn", "inspected_at")
    for n, inspected_at in enumerate(TIMES):
        body = {"inspection_id": f"I{n}", "inspected_at": inspected_at, "crack_length_m": 0.005}
        answer = client.post("/aircraft/H1/inspections", json=body)
        assert answer.status_code in (201, 422), answer.text
        assert (answer.status_code == 201) == bool(stated.search(inspected_at)), answer.text
