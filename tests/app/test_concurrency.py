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


def _sampled_tails(client: TestClient) -> float:
    for line in client.get("/metrics").text.splitlines():
        if line.startswith("fleetpinn_risk_sampled_tails_total "):
            return float(line.split()[1])
    raise AssertionError("no fleetpinn_risk_sampled_tails_total in /metrics")


def _three_tails_trained(client: TestClient) -> None:
    for tail, stress in (("R1", 110.0), ("R2", 140.0), ("R3", 170.0)):
        add_tail(client, tail, 200, stress=stress)
    inspect(client, "R1", START + timedelta(days=20), 0.00503)
    job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
    assert job["status"] == "succeeded", job


def test_concurrent_rankings_of_a_new_day_sample_the_fleet_once(client: TestClient) -> None:
    _three_tails_trained(client)
    before = _sampled_tails(client)
    start = threading.Barrier(6)
    answers: list[tuple[int, list[str]]] = []

    def rank() -> None:
        start.wait()
        answer = client.get("/fleet/ranking", params={"as_of": "2024-06-01"})
        answers.append((answer.status_code, [i["tail"] for i in answer.json()["items"]]))

    threads = [threading.Thread(target=rank) for _ in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert [status for status, _ in answers] == [200] * 6
    assert len({tuple(tails) for _, tails in answers}) == 1
    assert _sampled_tails(client) - before == 3  # one filler sampled each tail once


def test_rankings_survive_rows_dropped_and_advanced_meanwhile(client: TestClient) -> None:
    """Each round deletes a flight (its tail's rows dropped), adds an inspection (dropped
    again) and appends flights (rows advanced) while rankings of a new as-of date sample the
    risk of rows read before: no 500, every tail ranked exactly once."""
    _three_tails_trained(client)
    statuses: list[int] = []
    ranked: list[list[str]] = []
    for round_ in range(3):
        start = threading.Barrier(5)

        def rank(as_of: str, start: threading.Barrier) -> None:
            start.wait()
            answer = client.get("/fleet/ranking", params={"as_of": as_of})
            statuses.append(answer.status_code)
            if answer.status_code == 200:
                ranked.append(sorted(i["tail"] for i in answer.json()["items"]))

        def write(round_: int, start: threading.Barrier) -> None:
            start.wait()
            flight = f"F{round_ + 1:04d}"
            statuses.append(client.delete(f"/aircraft/R2/flights/{flight}").status_code)
            inspect(client, "R3", START + timedelta(days=30 + round_), 0.0051)
            more = [
                {
                    "flight_id": f"N{round_}",
                    "flown_at": (START + timedelta(days=70 + round_)).isoformat(),
                    "stress_range_mpa": 150.0,
                }
            ]
            statuses.append(client.post("/aircraft/R1/flights", json=more).status_code)

        days = [f"2024-0{7 + round_}-0{k + 1}" for k in range(4)]
        threads = [threading.Thread(target=rank, args=(d, start)) for d in days]
        threads.append(threading.Thread(target=write, args=(round_, start)))
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    assert statuses.count(200) == 3 * 5 and statuses.count(201) == 3, statuses
    assert ranked == [["R1", "R2", "R3"]] * (3 * 4)
    final = client.get("/fleet/ranking").json()["items"]
    assert sorted(i["tail"] for i in final) == ["R1", "R2", "R3"]
    flown = {i["tail"]: i["flights_flown"] for i in final}
    assert flown == {"R1": 203, "R2": 197, "R3": 200}
