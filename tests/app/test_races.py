"""Clients racing each other on a real uvicorn process, on each backend (issue 19): eight
clients creating the same new tail at once, and eight re-sending the same rows at once.  Every
answer is clean: one creation, the others find what it stored."""

from __future__ import annotations

import threading
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path

import httpx
import pytest

from app.local_server import ServiceProcess
from tests.app.conftest import flights
from tests.app.servers import client, server

CLIENTS = 8
TRIALS = 10


@pytest.fixture(scope="module")
def running(
    module_database_url: str, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[ServiceProcess]:
    process = server(module_database_url, Path(tmp_path_factory.mktemp("races")))
    try:
        yield process
    finally:
        process.stop()


def at_once(process: ServiceProcess, send: Callable[[httpx.Client], httpx.Response]) -> list:
    """The answers of CLIENTS clients (one connection each) sending at the same moment."""
    clients = [client(process) for _ in range(CLIENTS)]
    for each in clients:  # connect first, so the barrier releases requests, not handshakes
        each.get("/health")
    barrier = threading.Barrier(CLIENTS)
    answers: list[httpx.Response] = []

    def run(each: httpx.Client) -> None:
        barrier.wait()
        answers.append(send(each))

    threads = [threading.Thread(target=run, args=(each,)) for each in clients]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for each in clients:
        each.close()
    return answers


def test_clients_creating_one_new_tail_at_once_get_one_201_and_200s(
    running: ServiceProcess,
) -> None:
    for trial in range(TRIALS):
        tail = f"R{trial}"
        answers = at_once(
            running,
            lambda http, t=tail: http.put(f"/aircraft/{t}", json={"initial_crack_m": 0.004}),
        )
        statuses = Counter(a.status_code for a in answers)
        assert statuses == {201: 1, 200: CLIENTS - 1}, [a.text for a in answers]
        assert {a.json()["initial_crack_m"] for a in answers} == {0.004}
    with client(running) as http:
        listed = http.get("/aircraft", params={"limit": 1000}).json()["items"]
        assert sorted(a["tail"] for a in listed if a["tail"].startswith("R")) == sorted(
            f"R{trial}" for trial in range(TRIALS)
        )


def test_identical_rows_sent_at_once_are_stored_once_and_the_rest_are_duplicates(
    running: ServiceProcess,
) -> None:
    rows = flights(30)
    for trial in range(TRIALS):
        tail = f"D{trial}"
        with client(running) as http:
            assert http.put(f"/aircraft/{tail}").status_code == 201
        answers = at_once(
            running, lambda http, t=tail: http.post(f"/aircraft/{t}/flights", json=rows)
        )
        statuses = Counter(a.status_code for a in answers)
        assert statuses == {201: 1, 200: CLIENTS - 1}, [a.text for a in answers]
        bodies = [a.json() for a in answers]
        assert sum(b["inserted"] for b in bodies) == len(rows)
        assert sum(b["duplicates"] for b in bodies) == len(rows) * (CLIENTS - 1)
        with client(running) as http:
            assert http.get(f"/aircraft/{tail}").json()["flight_count"] == len(rows)


def test_the_same_new_tail_in_uploads_sent_at_once_is_created_once(
    running: ServiceProcess,
) -> None:
    csv = "tail,flight_id,flown_at,stress_range_mpa\n" + "".join(
        f"U{trial},F{trial},2024-01-0{1 + trial % 9}T00:00:00Z,100\n" for trial in range(3)
    )
    answers = at_once(
        running,
        lambda http: http.post("/flights/upload", files={"file": ("f.csv", csv, "text/csv")}),
    )
    statuses = Counter(a.status_code for a in answers)
    assert statuses == {201: 1, 200: CLIENTS - 1}, [a.text for a in answers]
    assert sum(a.json()["aircraft_created"] for a in answers) == 3
