"""A retrain whose worker died after storing its version (app.services.jobs.retrain_activation): the
job claimed again fits nothing and acts on the stored gate verdict as the dead attempt would
have, so a version that passed its gate becomes active after a restart exactly as without one
(issue 42: it stayed a candidate until an admin activated it)."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select, update

from app import worker
from app.config import Settings
from app.services import models as model_service
from app.services.forecasts import forecast_cache
from app.services.jobs import queue as jobs
from app.services.jobs import retrain, retrain_activation
from app.tables import Job, ModelVersion
from tests.app.conftest import START, add_tail, inspect, serving, settings_in

STRESSES = {f"T{i}": 120.0 + 15 * i for i in range(4)}


class _Killed(Exception):
    """The dead worker's last moment: raised where its process was killed."""


@pytest.fixture
def fleet(tmp_path: Path) -> Iterator[tuple[TestClient, Settings]]:
    """Four inspected tails and no worker thread: the test runs each attempt itself."""
    settings = settings_in(tmp_path).model_copy(
        update={"run_worker": False, "posterior_restarts": 1}
    )
    with serving(settings) as client:
        for i, (tail, stress) in enumerate(STRESSES.items()):
            add_tail(client, tail, 40, stress=stress)
            inspect(client, tail, START + timedelta(days=10), 0.0051 + 0.0001 * i)
        yield client, settings


def _run_all(client: TestClient, settings: Settings) -> None:
    factory = client.app.state.session_factory  # type: ignore[attr-defined]
    worker.run_pending(factory, settings, "w-test")


def _dies_after_storing(
    client: TestClient,
    settings: Settings,
    monkeypatch: pytest.MonkeyPatch,
    body: dict[str, Any],
    at: tuple[object, str] = (forecast_cache, "refresh"),
) -> tuple[str, int]:
    """Queue a retrain and run its first attempt until `at` (default: the fleet's refill), where
    its worker is killed: the version is stored, the job left running under a heartbeat gone
    stale.  Returns (job id, the version it stored)."""
    job_id = client.post("/models/retrain", json=body).json()["job_id"]
    factory = client.app.state.session_factory  # type: ignore[attr-defined]

    def killed(*args: Any, **kwargs: Any) -> int:
        raise _Killed

    with monkeypatch.context() as patch, factory() as session:
        patch.setattr(*at, killed)
        assert jobs.claim_next(session, "w-dead") == job_id
        params = dict(jobs.get_job(session, job_id).params)
        with pytest.raises(_Killed):
            retrain.run_retrain(
                session, job_id=job_id, params=params, settings=settings, progress=lambda *a: None
            )
    with factory() as session:
        stored = model_service.version_of_job(session, job_id)
        assert stored is not None
        assert model_service.get_version(session, stored).status == "candidate"
        old = datetime.now(UTC) - timedelta(hours=1)
        session.execute(update(Job).where(Job.id == job_id).values(heartbeat_at=old))
        session.commit()
        assert jobs.get_job(session, job_id).status == "running"
    return job_id, stored


def _versions_of(client: TestClient, job_id: str) -> int:
    factory = client.app.state.session_factory  # type: ignore[attr-defined]
    with factory() as session:
        query = select(func.count()).select_from(ModelVersion).where(ModelVersion.job_id == job_id)
        return int(session.scalar(query) or 0)


def test_a_version_that_passed_its_gate_is_activated_after_a_worker_restart(
    fleet: tuple[TestClient, Settings], monkeypatch: pytest.MonkeyPatch
) -> None:
    client, settings = fleet
    client.post("/models/retrain", json={})
    _run_all(client, settings)  # v1, uninterrupted: active
    assert client.get("/aircraft/T0/forecast").json()["model_version"] == 1
    job_id, stored = _dies_after_storing(client, settings, monkeypatch, {})
    assert stored == 2
    assert client.get("/aircraft/T0/forecast").json()["model_version"] == 1  # not switched
    _run_all(client, settings)  # the restarted worker claims the job again
    job = client.get(f"/jobs/{job_id}").json()
    assert (job["status"], job["outcome"]) == ("succeeded", "activated")
    gate = client.get("/models/2").json()["gate"]
    assert gate["passed"] and gate["active_version"] == 1
    # the gate's own reason, as an uninterrupted run reports it, and what happened
    assert job["outcome_reason"].startswith(gate["reason"])
    assert "earlier attempt of this job" in job["outcome_reason"]
    listed = {m["version"]: m["status"] for m in client.get("/models").json()}
    assert listed == {1: "retired", 2: "active"}
    assert _versions_of(client, job_id) == 1  # nothing fitted again
    # the fleet was refilled under v2 before the switch
    assert client.get("/aircraft/T0/forecast").json()["model_version"] == 2
    event = client.get("/audit", params={"action": "model.promote"}).json()["items"][0]
    assert event["subject"] == "model/2" and event["detail"]["job_id"] == job_id


def test_a_candidate_asked_for_stays_one_after_a_worker_restart(
    fleet: tuple[TestClient, Settings], monkeypatch: pytest.MonkeyPatch
) -> None:
    client, settings = fleet
    client.post("/models/retrain", json={})
    _run_all(client, settings)
    # no refill for a candidate: killed just before the verdict is acted on
    at = (retrain_activation, "_promote")
    job_id, stored = _dies_after_storing(client, settings, monkeypatch, {"activate": False}, at)
    _run_all(client, settings)
    job = client.get(f"/jobs/{job_id}").json()
    assert (job["status"], job["outcome"]) == ("succeeded", "candidate")
    assert job["outcome_reason"].startswith("stored as a candidate, as asked")
    listed = {m["version"]: m["status"] for m in client.get("/models").json()}
    assert listed == {1: "active", stored: "candidate"}
