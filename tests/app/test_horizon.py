"""One rule for a horizon: at most FLEETPINN_MAX_HORIZON_DAYS (3650) days after the as-of date,
refused beyond it with the bound named, on every route that takes one (5000 was capped to 3650
without a word while 100000 was refused quoting 36500)."""

from __future__ import annotations

from datetime import timedelta

import pytest
from fastapi.testclient import TestClient

from app.local_server import wait_for_job
from tests.app.conftest import START, add_tail, inspect
from tests.app.snapshots import copied_for_each_test


def _store_fleet(client: TestClient) -> None:
    """One tail of 8 flights, inspected, and the physics model active."""
    add_tail(client, "N1", 8)
    inspect(client, "N1", START + timedelta(days=1), 0.00501)
    job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
    assert job["status"] == "succeeded", job["error"]


stored_database, fleet = copied_for_each_test("fleet", _store_fleet)


@pytest.mark.parametrize("days", [5000, 100_000])
def test_a_horizon_past_the_bound_is_refused_naming_it(fleet: TestClient, days: int) -> None:
    for path in (
        "/aircraft/N1/forecast",
        "/fleet/ranking",
        "/forecasts",
        "/aircraft/N1/forecast.svg",
    ):
        answer = fleet.get(path, params={"horizon_days": days})
        assert answer.status_code == 422, path
        body = answer.json()
        assert body["detail"][0]["loc"] == ["query", "horizon_days"], path
        assert body["reason"] == (
            "Input should be less than or equal to 3650 (the service's FLEETPINN_MAX_HORIZON_DAYS)"
        ), path
    planned = fleet.post("/aircraft/N1/forecast", json={"horizon_days": days})
    assert planned.status_code == 422
    assert planned.json()["detail"][0]["loc"] == ["body", "horizon_days"]
    assert "3650" in planned.json()["reason"] and "36500" not in planned.text
    page = fleet.get("/pages/aircraft/N1", params={"horizon_days": days})
    assert page.status_code == 422 and "at most 3650" in page.text


def test_a_horizon_at_the_bound_is_served(fleet: TestClient) -> None:
    body = fleet.get("/aircraft/N1/forecast", params={"horizon_days": 3650}).json()
    assert body["horizon_days"] == 3650
    assert fleet.get("/fleet/ranking").json()["horizon_days"] == 365  # the default
