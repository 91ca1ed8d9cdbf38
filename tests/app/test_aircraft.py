from datetime import timedelta

from fastapi.testclient import TestClient

from app.local_server import wait_for_job
from tests.app.conftest import START, add_tail, inspect


def test_put_creates_then_updates(client: TestClient) -> None:
    created = client.put("/aircraft/N001")
    assert created.status_code == 201
    assert created.json()["initial_crack_m"] is None
    updated = client.put("/aircraft/N001", json={"initial_crack_m": 0.006})
    assert updated.status_code == 200
    assert updated.json()["initial_crack_m"] == 0.006
    assert client.put("/aircraft/N001", json={"initial_crack_m": -1}).status_code == 422


def test_get_reports_counts_and_last_flight(client: TestClient) -> None:
    add_tail(client, "N001", 10)
    inspect(client, "N001", START + timedelta(days=3), 0.0051)
    body = client.get("/aircraft/N001").json()
    assert body["flight_count"] == 10
    assert body["inspection_count"] == 1
    # 10 flights at 4 a day: the last at day 2, 06:00.
    assert body["last_flown_at"] == "2024-01-03T06:00:00Z"


def test_unknown_tail_is_404(client: TestClient) -> None:
    answer = client.get("/aircraft/NOPE")
    assert answer.status_code == 404
    assert "NOPE" in answer.json()["detail"]


def test_list_is_paginated_by_tail(client: TestClient) -> None:
    for tail in ("C", "A", "B"):
        client.put(f"/aircraft/{tail}")
    page = client.get("/aircraft", params={"limit": 2, "offset": 1}).json()
    assert page["total"] == 3
    assert [a["tail"] for a in page["items"]] == ["B", "C"]
    assert client.get("/aircraft", params={"limit": 0}).status_code == 422


def test_tail_with_surrounding_whitespace_is_rejected(client: TestClient) -> None:
    assert client.put("/aircraft/%20N1").status_code == 422
    assert client.put("/aircraft/N%201").status_code == 201


def test_an_admin_deletes_a_tail_with_its_records(client: TestClient) -> None:
    """The tour's own tail goes away at its end, with its flights, inspections and forecasts."""
    add_tail(client, "GONE", 10)
    add_tail(client, "KEPT", 10)
    inspect(client, "GONE", START + timedelta(days=1), 0.0051)
    job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
    assert job["status"] == "succeeded", job["error"]
    assert {i["tail"] for i in client.get("/fleet/ranking").json()["items"]} == {"GONE", "KEPT"}
    removed = client.delete("/aircraft/GONE")
    assert removed.status_code == 200
    assert (removed.json()["flight_count"], removed.json()["inspection_count"]) == (10, 1)
    assert client.get("/aircraft/GONE").status_code == 404
    assert client.get("/aircraft/GONE/forecast").status_code == 404
    assert [i["tail"] for i in client.get("/fleet/ranking").json()["items"]] == ["KEPT"]
    assert client.delete("/aircraft/GONE").status_code == 404
    event = client.get("/audit", params={"action": "aircraft.delete"}).json()["items"][0]
    assert event["subject"] == "GONE" and event["detail"]["flights"] == 10
