"""End to end: a real `python -m uvicorn` process over HTTP, with its in-process worker, on
each backend."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from datetime import timedelta
from pathlib import Path

import httpx
import pandas as pd
import pytest

from app import commands
from app.config import Settings
from app.local_server import uvicorn_server, wait_for_job
from tests.app.conftest import START, bearer, flights
from tests.app.servers import BASE_ENV


@pytest.fixture(scope="module")
def server_database(module_database_url: str) -> Settings:
    """The database of the module's server, on each backend (for keys made beside it)."""
    return Settings(database_url=module_database_url)


@pytest.fixture(scope="module")
def server_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Where the module's server writes its output."""
    return tmp_path_factory.mktemp("e2e") / "server.log"


@pytest.fixture(scope="module")
def server(server_database: Settings, server_log: Path) -> Iterator[httpx.Client]:
    """A real uvicorn on a fresh database (its log in server_log); the client sends an admin
    key."""
    env = {**BASE_ENV, "FLEETPINN_DATABASE_URL": server_database.database_url}
    with uvicorn_server("app.main:app", env, log=server_log) as base:
        key = commands.create_key("admin", "e2e", settings=server_database).key
        with httpx.Client(base_url=base, timeout=30, headers=bearer(key)) as client:
            yield client


def test_upload_retrain_forecast_over_http(server: httpx.Client) -> None:
    assert server.get("/ready").json()["model_version"] is None
    rows = [
        {"tail": t, **f} for t, s in (("E1", 120.0), ("E2", 160.0)) for f in flights(40, stress=s)
    ]
    csv = pd.DataFrame(rows).to_csv(index=False)
    upload = server.post("/flights/upload", files={"file": ("fleet.csv", csv, "text/csv")})
    assert upload.status_code == 201
    assert upload.json() == {"inserted": 80, "duplicates": 0, "aircraft_created": 2}
    inspection = {
        "inspection_id": "I1",
        "inspected_at": (START + timedelta(days=10)).isoformat(),
        "crack_length_m": 0.00502,
    }
    assert server.post("/aircraft/E1/inspections", json=inspection).status_code == 201

    job = wait_for_job(server, server.post("/models/retrain").json()["job_id"])
    assert job["status"] == "succeeded", job
    assert server.get("/ready").json() == {
        "status": "ready",
        "database": True,
        "model_version": 1,
        "model_versions": {"default": 1},
    }

    forecast = server.get("/aircraft/E2/forecast", params={"horizon_days": 10}).json()
    assert forecast["flights_flown"] == 40
    assert len(forecast["trajectory"]) == 11
    ranking = server.get("/fleet/ranking").json()
    assert [item["tail"] for item in ranking["items"]] == ["E2", "E1"]
    assert server.get("/docs").status_code == 200
    listed = server.get("/aircraft").json()
    assert {a["tail"]: a["flight_count"] for a in listed["items"]} == {"E1": 40, "E2": 40}


def test_http_forecast_equals_offline_predict(server: httpx.Client, tmp_path: Path) -> None:
    """The served crack after the last flight equals `fleetpinn predict` with the served model file."""
    rows = [
        {"tail": t, **f}
        for t, s in (("P1", [95.0, 130.0]), ("P2", [110.0, 100.0, 140.0]))
        for f in flights(60, stress=s)
    ]
    csv_path = tmp_path / "flights.csv"
    pd.DataFrame(rows).to_csv(csv_path, index=False)
    with csv_path.open("rb") as handle:
        assert server.post("/flights/upload", files={"file": handle}).status_code == 201
    for tail, crack in (("P1", 0.00506), ("P2", 0.00507)):
        inspection = {
            "inspection_id": "I1",
            "inspected_at": (START + timedelta(days=20)).isoformat(),
            "crack_length_m": crack,
        }
        assert server.post(f"/aircraft/{tail}/inspections", json=inspection).status_code == 201
    body = {"kernel": "residual", "lbfgs_iterations": 10}
    job = wait_for_job(server, server.post("/models/retrain", json=body).json()["job_id"])
    assert job["status"] == "succeeded", job
    version = job["model_version"]
    download = server.get(f"/models/{version}/file")
    assert download.status_code == 200
    model_path = tmp_path / "model.pt"
    model_path.write_bytes(download.content)

    out = tmp_path / "pred.csv"
    fleetpinn = Path(sys.executable).parent / "fleetpinn"
    subprocess.run(
        [fleetpinn, "predict", "--model", model_path, "--flights", csv_path, "--out", out],
        check=True,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    offline = pd.read_csv(out).set_index("tail")
    for tail in ("P1", "P2"):
        served = server.get(f"/aircraft/{tail}/forecast", params={"horizon_days": 1}).json()
        assert served["model_version"] == version
        assert served["flights_flown"] == offline.loc[tail, "flights"] == 60
        # the service's point is at the tail's own posterior median factor, predict's without
        # --inspections at the fleet's: its inspection moves it a little
        assert served["crack_length_m"] == pytest.approx(
            offline.loc[tail, "crack_length_m"], rel=1e-5
        )
    assert server.get("/models/999/file").status_code == 404


def test_json_log_lines_for_requests_and_jobs(server: httpx.Client, server_log: Path) -> None:
    """One JSON line per request (request id, route template, status, duration, key name) and
    a line when a job starts and ends, sharing the id of the request that queued it."""
    server.get("/aircraft/NOPE", headers={"X-Request-ID": "e2e-lookup"})
    queued = server.post("/models/retrain", headers={"X-Request-ID": "e2e-retrain"})
    wait_for_job(server, queued.json()["job_id"])
    log = server_log
    lines = [json.loads(line) for line in log.read_text().splitlines() if line.startswith("{")]
    [lookup] = [
        line
        for line in lines
        if line["logger"] == "fleetpinn.request" and line["request_id"] == "e2e-lookup"
    ]
    assert (lookup["route"], lookup["path"], lookup["status"]) == (
        "/aircraft/{tail}",
        "/aircraft/NOPE",
        404,
    )
    assert lookup["key"] == "e2e" and lookup["duration_ms"] > 0 and lookup["method"] == "GET"
    job_lines = [
        line
        for line in lines
        if line["logger"] == "fleetpinn.worker" and line.get("job_id") == queued.json()["job_id"]
    ]
    started, ended = job_lines
    assert started["message"].endswith("started, attempt 1") and "status" not in started
    assert ended["status"] in ("succeeded", "failed") and ended["kind"] == "retrain"
    assert {line["request_id"] for line in job_lines} == {"e2e-retrain"}
    assert job_lines[1]["duration_s"] >= 0 and job_lines[1]["requested_by"] == "e2e"


def test_concurrent_corrections_lose_no_update(server: httpx.Client) -> None:
    """Eight clients correct one inspection at once: each answer is 200 or a 409 (changed
    meanwhile), never a 5xx, and the audit log chains the successful ones without a gap."""
    assert server.put("/aircraft/C9").status_code == 201
    assert server.post("/aircraft/C9/flights", json=flights(4)).status_code == 201
    first = {"inspection_id": "I1", "inspected_at": START.isoformat(), "crack_length_m": 0.005}
    assert server.post("/aircraft/C9/inspections", json=first).status_code == 201
    values = [0.0051 + 0.0001 * i for i in range(8)]

    def correct(value: float) -> int:
        body = {"crack_length_m": value}
        return server.patch("/aircraft/C9/inspections/I1", json=body).status_code

    with ThreadPoolExecutor(max_workers=8) as pool:
        statuses = list(pool.map(correct, values))
    assert set(statuses) <= {200, 409} and 200 in statuses, statuses
    events = server.get("/audit", params={"subject": "C9/I1", "limit": 50}).json()["items"]
    befores = [e["detail"]["before"]["crack_length_m"] for e in reversed(events)]
    assert len(befores) == statuses.count(200)
    final = server.get("/aircraft/C9/inspections/I1").json()["crack_length_m"]
    applied = [v for v, s in zip(values, statuses, strict=True) if s == 200]
    # each correction saw the value the one before it left: the first the original
    assert befores[0] == 0.005 and set(befores[1:]) | {final} == set(applied)
