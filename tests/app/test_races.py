"""Clients racing each other on a real uvicorn process, on each backend (issue 19): eight
clients creating the same new tail at once, and eight re-sending the same rows at once.  Every
answer is clean: one creation, the others find what it stored."""

from __future__ import annotations

import itertools
import threading
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path

import httpx
import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db import make_engine
from app.local_server import ServiceProcess
from app.services.records import spectra
from app.tables import Aircraft
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


def test_flights_sent_as_cycles_at_once_each_keep_their_own_cycles(
    running: ServiceProcess, module_database_url: str
) -> None:
    """Clients storing flights as cycles at once, each on its own tail: the flights' and their
    spectrum blocks' ids are reserved before their insert (app.storage next_ids), so no two
    requests take the same ones and every flight's stored cycles are its own."""
    tails = [f"S{k}" for k in range(CLIENTS)]
    with client(running) as http:
        for tail in tails:
            assert http.put(f"/aircraft/{tail}").status_code == 201
    turn = itertools.count()

    def send(http: httpx.Client) -> httpx.Response:
        k = next(turn)
        body = [
            {
                "flight_id": f"F{i}",
                "flown_at": f"2024-01-01T{i:02d}:00:00Z",
                "cycles": [
                    {"stress_range_mpa": 100.0 + k, "load_ratio": 0.1},
                    {"stress_range_mpa": 10.0 * (i + 1), "load_ratio": 0.5, "count": 2},
                ],
            }
            for i in range(20)
        ]
        return http.post(f"/aircraft/{tails[k]}/flights", json=body)

    answers = at_once(running, send)
    assert [a.status_code for a in answers] == [201] * CLIENTS, [a.text for a in answers]
    engine = make_engine(module_database_url)
    try:
        with Session(engine) as session:
            for k, tail in enumerate(tails):
                aircraft = session.scalar(select(Aircraft.id).where(Aircraft.tail == tail))
                assert aircraft is not None
                for i in range(20):
                    sent = spectra.stored(session, aircraft, f"F{i}")
                    assert sent is not None
                    assert sent.cycles.stress_range_mpa.tolist() == [100.0 + k, 10.0 * (i + 1)]
    finally:
        engine.dispose()
