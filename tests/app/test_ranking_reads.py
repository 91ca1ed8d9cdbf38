"""What a ranking made anew after a change reads, counted in statements (no timing): the
page's inspections and last flights once for the page whatever its locations (app.services.
ranking.ranking_page), and each active version's fingerprint only where ranking_answers reads them,
not again per version (app.services.ranking.order.ordered's `known`).  The answers are the ones
made from scratch."""

from __future__ import annotations

from datetime import timedelta
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.local_server import wait_for_job
from tests.app.conftest import (
    START,
    add_tail,
    forget_kept_answers,
    inspect,
    later_flights,
    retrained,
    statements,
)


@pytest.fixture
def two_locations(client: TestClient) -> TestClient:
    """Three tails of 40 flights, LOW inspected at the default location and the wing, the
    physics active at both."""
    for tail, stress in {"LOW": 100.0, "MID": 150.0, "HIGH": 200.0}.items():
        add_tail(client, tail, 40, stress=stress)
    inspect(client, "LOW", START + timedelta(days=10, hours=1), 0.0051)
    retrained(client)
    wing = {"stress_factor": 1.5, "initial_crack_m": 0.002}
    assert client.put("/locations/wing", json=wing).status_code in (200, 201)
    body = {
        "inspection_id": "W1",
        "inspected_at": (START + timedelta(days=10, hours=1)).isoformat(),
        "crack_length_m": 0.003,
        "location": "wing",
    }
    assert client.post("/aircraft/LOW/inspections", json=body).status_code == 201
    for job in client.post("/models/retrain").json()["jobs"].values():
        assert wait_for_job(client, job)["status"] == "succeeded"
    return client


def _ranking(client: TestClient) -> dict[str, Any]:
    answer = client.get("/fleet/ranking")
    assert answer.status_code == 200, answer.text
    body: dict[str, Any] = answer.json()
    return body


def test_a_ranking_made_anew_reads_its_page_and_fingerprints_once(
    two_locations: TestClient,
) -> None:
    _ranking(two_locations)
    later_flights(two_locations, "MID")  # the next ranking is made anew
    with statements(two_locations) as seen:
        after = _ranking(two_locations)
    assert {item["location"] for item in after["items"]} == {"default", "wing"}
    on_inspections = [s for s in seen if "from inspections" in s]
    fingerprints = [s for s in seen if "sum(" in s]
    # the last inspections, the flagged ones and the repairs: once for both locations (per
    # location: six); every active version's fingerprint before and after the answer's lock
    # (per version as well: six)
    assert len(on_inspections) == 3, on_inspections
    assert len(fingerprints) == 2, fingerprints
    assert after == _from_scratch(two_locations)


def _from_scratch(client: TestClient) -> dict[str, Any]:
    forget_kept_answers()
    return _ranking(client)
