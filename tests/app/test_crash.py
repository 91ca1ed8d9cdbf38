"""Crash safety with real processes and a real `kill -9`, on each backend.

A server killed during a bulk upload leaves none of it; a server or a `fleetpinn worker` killed
during a retrain leaves the active model as it was and no partial version, and the job runs
again, once, when its heartbeat has gone stale (job_stale_seconds), making exactly one version.

They run beside other tests (Makefile pytest): one process claims jobs at a time, so a heartbeat
late on a busy machine delays nothing and cannot make a second run.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pandas as pd
import pytest
from sqlalchemy import Engine, func, select, text

from app.db import make_engine
from app.tables import Flight, Job, ModelVersion
from tests.app.conftest import flights
from tests.app.servers import client, server, worker

# Long histories must end before today (records dated in the future are refused).
EARLY = datetime(2020, 1, 1, tzinfo=UTC)
# Stale after 2 s (beats every 0.2 s): a dead worker's job is claimed again quickly.
FAST_RECOVERY = {"FLEETPINN_JOB_STALE_SECONDS": "2"}
# A hybrid retrain that takes seconds, so it can be caught running.
SLOW_RETRAIN = {"kernel": "residual", "lbfgs_iterations": 60}


@pytest.fixture
def engine(database_url: str) -> Iterator[Engine]:
    engine = make_engine(database_url)
    yield engine
    engine.dispose()


def _scalar(engine: Engine, query: object) -> object:
    with engine.connect() as connection:
        return connection.execute(query).scalar()  # type: ignore[call-overload]


def _until(condition: Callable[[], bool], timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.02)


def _fleet_csv(tails: int, per_tail: int) -> str:
    rows = [
        {"tail": f"K{t:03d}", **f}
        for t in range(tails)
        for f in flights(per_tail, stress=[90.0 + t, 130.0, 110.0], start=EARLY)
    ]
    return pd.DataFrame(rows).to_csv(index=False)


def _inserting(engine: Engine, database_url: str, wal: Path) -> Callable[[], bool]:
    """True once the upload's rows are going into the database, before its commit."""
    if database_url.startswith("postgresql"):
        query = text(
            "SELECT count(*) FROM pg_stat_activity WHERE state = 'active' "
            "AND query LIKE 'COPY flights%'"
        )
        return lambda: bool(_scalar(engine, query))
    # SQLite spills the open transaction's pages to the write-ahead log as it inserts.
    return lambda: wal.exists() and wal.stat().st_size > 4_000_000


def test_kill_during_a_bulk_upload_stores_none_of_it(
    database_url: str, engine: Engine, tmp_path: Path
) -> None:
    import threading

    import httpx

    running = server(database_url, tmp_path)
    csv = _fleet_csv(40, 5000)  # 200,000 flights
    outcome: dict[str, object] = {}

    def upload() -> None:
        try:
            with client(running, timeout_s=120) as http:
                files = {"file": ("fleet.csv", csv, "text/csv")}
                outcome["status"] = http.post("/flights/upload", files=files).status_code
        except httpx.HTTPError as exc:
            outcome["error"] = exc

    sender = threading.Thread(target=upload)
    sender.start()
    wal = Path(database_url.removeprefix("sqlite:///") + "-wal")
    inserting = _inserting(engine, database_url, wal)
    try:
        _until(lambda: inserting() or not sender.is_alive(), 120, "the upload's insert")
    finally:
        running.kill()
    sender.join()
    assert "status" not in outcome, f"the upload finished before the kill: {outcome}"
    restarted = server(database_url, tmp_path)
    try:
        with client(restarted) as http:
            assert http.get("/aircraft").json()["total"] == 0
        assert _scalar(engine, select(func.count()).select_from(Flight)) == 0
    finally:
        restarted.stop()


def _fleet_and_first_version(client: object, engine: Engine) -> None:
    """6 tails of 3,000 flights, 4 inspected, and a physics model (fast) retrained and active as
    version 1.  A location has one queued retrain at a time (app.services.jobs.queue), so the hybrid
    one that is killed (_slow_retrain) is queued after this one has run."""
    import httpx

    assert isinstance(client, httpx.Client)
    csv = _fleet_csv(6, 3000)
    assert client.post("/flights/upload", files={"file": ("f.csv", csv, "text/csv")}).is_success
    for t in range(4):
        body = {
            "inspection_id": "I1",
            "inspected_at": (EARLY + timedelta(days=700)).isoformat(),
            "crack_length_m": 0.0060 + 0.0003 * t,
        }
        assert client.post(f"/aircraft/K{t:03d}/inspections", json=body).status_code == 201
    first = client.post("/models/retrain", json={"kernel": "physics"}).json()["job_id"]
    done = select(Job.status).where(Job.id == first)
    _until(lambda: _scalar(engine, done) == "succeeded", 120, "the physics retrain")


def _slow_retrain(client: object) -> str:
    """Queue a hybrid retrain (seconds) and return its job."""
    import httpx

    assert isinstance(client, httpx.Client)
    job_id: str = client.post("/models/retrain", json=SLOW_RETRAIN).json()["job_id"]
    return job_id


def _running(engine: Engine, job_id: str) -> Callable[[], bool]:
    """True once the job is training (its history is loaded)."""
    query = select(Job.progress).where(Job.id == job_id, Job.status == "running")
    return lambda: (_scalar(engine, query) or 0.0) >= 0.05  # type: ignore[operator]


def _assert_untouched_then_run_once(engine: Engine, job_id: str) -> None:
    """Right after the kill: version 1 still active, nothing stored by the job."""
    assert _scalar(engine, select(ModelVersion.version).where(ModelVersion.status == "active")) == 1
    assert _scalar(engine, select(func.count()).where(ModelVersion.job_id == job_id)) == 0


def _assert_ran_again_once(engine: Engine, job_id: str) -> None:
    status = select(Job.status).where(Job.id == job_id)
    _until(lambda: _scalar(engine, status) in ("succeeded", "failed"), 180, "the re-run")
    assert _scalar(engine, status) == "succeeded"
    assert _scalar(engine, select(Job.attempts).where(Job.id == job_id)) == 2
    versions = select(func.count()).select_from(ModelVersion)
    assert _scalar(engine, versions) == 2  # the physics model and this job's, once
    active = select(ModelVersion.job_id).where(ModelVersion.status == "active")
    assert _scalar(engine, active) == job_id


# A kill during a retrain on the backend of its layout (the server's own worker thread: `make
# demo` on SQLite; `fleetpinn worker` processes: a deployment on PostgreSQL), so a stale job's
# claim is still tried on each backend: each test starts three processes (~10 s of CPU each).
@pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
def test_kill_a_server_during_a_retrain(database_url: str, engine: Engine, tmp_path: Path) -> None:
    running = server(database_url, tmp_path, **FAST_RECOVERY)
    with client(running) as http:
        _fleet_and_first_version(http, engine)
        job_id = _slow_retrain(http)
    try:
        _until(_running(engine, job_id), 180, "the retrain to start")
    finally:
        running.kill()
    _assert_untouched_then_run_once(engine, job_id)
    restarted = server(database_url, tmp_path, **FAST_RECOVERY)
    try:
        _assert_ran_again_once(engine, job_id)
    finally:
        restarted.stop()


@pytest.mark.parametrize("database_url", ["postgresql"], indirect=True)
def test_kill_a_worker_mid_job(database_url: str, engine: Engine, tmp_path: Path) -> None:
    running = server(database_url, tmp_path)
    try:
        with client(running) as http:
            _fleet_and_first_version(http, engine)
    finally:
        running.stop()
    running = server(database_url, tmp_path, FLEETPINN_RUN_WORKER="0")
    try:
        with client(running) as http:
            job_id = _slow_retrain(http)
    finally:
        running.stop()
    doomed = worker(database_url, tmp_path, **FAST_RECOVERY)
    try:
        _until(_running(engine, job_id), 180, "the worker to start the retrain")
    finally:
        doomed.kill()
    _assert_untouched_then_run_once(engine, job_id)
    survivor = worker(database_url, tmp_path, **FAST_RECOVERY)
    try:
        _assert_ran_again_once(engine, job_id)
    finally:
        survivor.stop()
