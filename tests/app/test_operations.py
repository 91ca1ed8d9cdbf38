"""Operations: Prometheus /metrics, X-Request-ID, a JSON 500 without traceback, the logs'
format, the Dockerfile's health check.  (The request and job log lines of a real server are
checked in test_e2e.py.)"""

from __future__ import annotations

import io
import json
import logging
import os
import socket
from pathlib import Path

import httpx
import pytest
from fastapi.testclient import TestClient
from prometheus_client.parser import text_string_to_metric_families
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import Response
from starlette.routing import Route

from app import commands, logs
from app.config import Settings
from app.local_server import wait_for_job
from app.middleware import RequestContext
from tests.app.conftest import START, add_tail, inspect


def _samples(client: TestClient) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    answer = client.get("/metrics", headers={"Authorization": ""})
    assert answer.status_code == 200
    assert answer.headers["content-type"].startswith("text/plain")
    return {
        (s.name, tuple(sorted(s.labels.items()))): s.value
        for family in text_string_to_metric_families(answer.text)
        for s in family.samples
    }


def test_metrics_count_requests_ingests_and_retrains(client: TestClient) -> None:
    before = _samples(client)
    add_tail(client, "N1", 12)
    inspect(client, "N1", START, 0.005)
    client.get("/aircraft/N1")
    client.get("/aircraft/N2")  # 404: counted under its template too
    job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
    after = _samples(client)

    def delta(name: str, **labels: str) -> float:
        key = (name, tuple(sorted(labels.items())))
        return after.get(key, 0.0) - before.get(key, 0.0)

    route = {"method": "GET", "route": "/aircraft/{tail}"}
    assert delta("fleetpinn_http_request_duration_seconds_count", **route) == 2
    assert delta("fleetpinn_http_requests_total", **route, status="200") == 1
    assert delta("fleetpinn_http_requests_total", **route, status="404") == 1
    assert delta("fleetpinn_ingest_rows_total", kind="flights", outcome="inserted") == 12
    assert delta("fleetpinn_ingest_rows_total", kind="inspections", outcome="inserted") == 1
    assert delta("fleetpinn_retrain_duration_seconds_count", outcome="activated") == 1
    assert delta("fleetpinn_jobs_finished_total", kind="retrain", status="succeeded") == 1
    assert after[("fleetpinn_active_model_version", ())] == job["model_version"] == 1
    assert after[("fleetpinn_jobs", (("status", "succeeded"),))] == 1


def test_request_ids_are_echoed_or_made(client: TestClient) -> None:
    given = client.get("/health", headers={"X-Request-ID": "tool-42.a"})
    assert given.headers["x-request-id"] == "tool-42.a"
    made = client.get("/health").headers["x-request-id"]
    assert len(made) == 32 and int(made, 16) >= 0
    odd = client.get("/health", headers={"X-Request-ID": "a b\tc"}).headers["x-request-id"]
    assert odd != "a b\tc" and len(odd) == 32
    assert client.get("/aircraft", headers={"Authorization": ""}).headers["x-request-id"]


def test_a_request_id_is_made_without_a_system_call(
    client: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    """uuid4 read os.urandom on the event loop for every request: a system call that hands the
    GIL to the request threads (app.middleware._RequestIds)."""

    def refused(size: int) -> bytes:
        raise AssertionError(f"os.urandom({size}) read for a request")

    monkeypatch.setattr(os, "urandom", refused)
    made = [client.get("/health").headers["x-request-id"] for _ in range(3)]
    assert len(set(made)) == 3
    assert all(len(made_id) == 32 and int(made_id, 16) >= 0 for made_id in made)


def _broken(_: Request) -> Response:
    raise RuntimeError("secret internals")


def test_an_unhandled_error_is_a_json_500_without_traceback() -> None:
    app = Starlette(routes=[Route("/broken", _broken)])
    app.add_middleware(RequestContext)
    with TestClient(app, raise_server_exceptions=False) as client:
        answer = client.get("/broken", headers={"X-Request-ID": "r-1"})
    assert answer.status_code == 500
    assert answer.json() == {
        "detail": "internal server error; the log has the details",
        "request_id": "r-1",
    }
    assert answer.headers["x-request-id"] == "r-1"
    assert "secret internals" not in answer.text and "Traceback" not in answer.text


def test_json_logs_carry_the_request_id() -> None:
    logs.configure("json", "INFO")
    root = logging.getLogger()
    [handler] = [h for h in root.handlers if h.get_name() == "fleetpinn"]
    stream = io.StringIO()
    handler.setStream(stream)  # type: ignore[attr-defined]
    token = logs.REQUEST_ID.set("req-7")
    try:
        logging.getLogger("fleetpinn.test").info("hello %s", "there", extra={"status": 201})
    finally:
        logs.REQUEST_ID.reset(token)
    line = json.loads(stream.getvalue().strip().splitlines()[-1])
    assert line["message"] == "hello there" and line["level"] == "INFO"
    assert (line["request_id"], line["status"], line["logger"]) == ("req-7", 201, "fleetpinn.test")
    logs.configure("json", "INFO")  # a fresh handler again, never a second one
    assert len([h for h in root.handlers if h.get_name() == "fleetpinn"]) == 1


def test_docker_healthcheck_asks_for_readiness() -> None:
    dockerfile = (Path(__file__).parents[2] / "Dockerfile").read_text()
    [check] = [line for line in dockerfile.splitlines() if line.strip().startswith("CMD python")]
    assert "/ready" in check


def test_a_worker_process_serves_its_own_metrics(tmp_path: Path) -> None:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    settings = Settings(database_url=f"sqlite:///{tmp_path / 'w.db'}")
    assert commands.worker(once=True, metrics_port=port, settings=settings) == 0
    scraped = httpx.get(f"http://127.0.0.1:{port}/metrics", timeout=5).text
    assert "fleetpinn_jobs_finished_total" in scraped
    assert "fleetpinn_retrain_duration_seconds" in scraped


def test_a_worker_s_metrics_listen_on_loopback_unless_told(tmp_path: Path) -> None:
    """`serve` defaults to 127.0.0.1; the worker's metrics listened on every interface."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    settings = Settings(database_url=f"sqlite:///{tmp_path / 'w.db'}")
    assert commands.worker(once=True, metrics_port=port, settings=settings) == 0
    # (local address, state) of the sockets on the port; 0A: listening, 0100007F: 127.0.0.1
    table = Path("/proc/net/tcp").read_text().splitlines()[1:]
    bound = [(r.split()[1], r.split()[3]) for r in table if r.split()[1].endswith(f":{port:04X}")]
    assert (f"0100007F:{port:04X}", "0A") in bound and all(
        a.startswith("0100007F") for a, _ in bound
    ), bound
