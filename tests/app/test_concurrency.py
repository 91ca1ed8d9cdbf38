"""Many requests at once on one server process, on each backend: the forecast cache is filled
once per tail and version, and every request gets the same answer."""

from __future__ import annotations

import threading
from datetime import timedelta

from fastapi.testclient import TestClient

from app.local_server import wait_for_job
from tests.app.conftest import START, add_tail, inspect


def test_concurrent_requests_for_a_cold_tail_agree(client: TestClient) -> None:
    for tail, stress in (("C1", 110.0), ("C2", 140.0)):
        add_tail(client, tail, 200, stress=stress)
    inspect(client, "C1", START + timedelta(days=20), 0.00503)
    job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
    assert job["status"] == "succeeded", job
    # New flights void C2's cached state: every request below finds it missing at once.
    more = [
        {
            "flight_id": "X1",
            "flown_at": (START + timedelta(days=60)).isoformat(),
            "stress_range_mpa": 150.0,
        }
    ]
    assert client.post("/aircraft/C2/flights", json=more).status_code == 201
    answers: list[tuple[int, float | None]] = []
    start = threading.Barrier(8)

    def ask(path: str) -> None:
        start.wait()
        answer = client.get(path)
        body = answer.json()
        crack = (
            body["crack_length_m"]
            if "crack_length_m" in body
            else body["items"][0]["crack_length_m"]
        )
        answers.append((answer.status_code, crack))

    paths = ["/aircraft/C2/forecast"] * 5 + ["/fleet/ranking?by=crack"] * 3
    threads = [threading.Thread(target=ask, args=(p,)) for p in paths]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert [status for status, _ in answers] == [200] * 8
    assert len({crack for _, crack in answers}) == 1  # C2 (the larger crack) everywhere
    assert client.get("/aircraft/C2/forecast").json()["flights_flown"] == 201
