"""The queue without the worker thread: claiming, cancelling."""

from collections.abc import Iterator
from datetime import UTC, datetime, timedelta

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import update
from sqlalchemy.orm import Session

from app import migrate
from app.config import Settings, get_settings
from app.db import make_engine, make_session_factory
from app.main import create_app
from app.services import audit
from app.services.jobs import queue as jobs
from app.tables import Job
from tests.app.conftest import bearer, new_key

TESTER = audit.local("test")


@pytest.fixture
def session(settings: Settings) -> Iterator[Session]:
    migrate.upgrade(settings.database_url)
    engine = make_engine(settings.database_url)
    with make_session_factory(engine)() as s:
        yield s
    engine.dispose()


def test_claim_takes_the_oldest_queued_job_once(session: Session) -> None:
    first = jobs.enqueue(session, "retrain", {}, actor=TESTER).id
    second = jobs.enqueue(session, "forecast-batch", {}, actor=TESTER).id
    assert jobs.claim_next(session, "w1") == first
    assert jobs.claim_next(session, "w2") == second
    assert jobs.claim_next(session, "w3") is None
    assert jobs.get_job(session, first).worker == "w1"
    assert jobs.get_job(session, first).status == "running"


def test_cancel_queued_and_running(session: Session) -> None:
    queued = jobs.enqueue(session, "retrain", {}, actor=TESTER).id
    assert jobs.cancel(session, queued, actor=TESTER).status == "cancelled"
    running = jobs.enqueue(session, "retrain", {}, actor=TESTER).id
    assert jobs.claim_next(session, "w") == running
    assert jobs.cancel(session, running, actor=TESTER).status == "running"
    assert jobs.report_progress(session, running, 0.5) is True


def test_cancel_endpoint_without_worker(settings: Settings) -> None:
    app = create_app()
    quiet = settings.model_copy(update={"run_worker": False})
    app.dependency_overrides[get_settings] = lambda: quiet
    with TestClient(app) as client:
        client.headers.update(bearer(new_key(app, "write")))
        job_id = client.post("/models/retrain").json()["job_id"]
        assert client.get(f"/jobs/{job_id}").json()["status"] == "queued"
        assert client.post(f"/jobs/{job_id}/cancel").json()["status"] == "cancelled"
        assert client.post(f"/jobs/{job_id}/cancel").status_code == 409


def _stale(session: Session, job_id: str) -> None:
    old = datetime.now(UTC) - timedelta(hours=1)
    session.execute(update(Job).where(Job.id == job_id).values(heartbeat_at=old))
    session.commit()


def test_a_job_whose_worker_died_is_claimed_again(session: Session) -> None:
    job_id = jobs.enqueue(session, "retrain", {}, actor=TESTER).id
    assert jobs.claim_next(session, "w1") == job_id
    # Still beating: nobody else takes it.
    assert jobs.claim_next(session, "w2", stale_after_s=60) is None
    _stale(session, job_id)
    assert jobs.claim_next(session, "w2", stale_after_s=60) == job_id
    job = jobs.get_job(session, job_id)
    session.refresh(job)
    assert (job.worker, job.attempts, job.status) == ("w2", 2, "running")


def test_a_job_abandoned_too_often_fails(session: Session) -> None:
    job_id = jobs.enqueue(session, "retrain", {}, actor=TESTER).id
    for _ in range(jobs.MAX_ATTEMPTS):
        assert jobs.claim_next(session, "w", stale_after_s=60) == job_id
        _stale(session, job_id)
    assert jobs.claim_next(session, "w", stale_after_s=60) is None
    job = jobs.get_job(session, job_id)
    session.refresh(job)
    assert job.status == "failed"
    assert "abandoned" in (job.error or "")


def test_progress_reports_a_new_stage_at_once(session: Session, settings: Settings) -> None:
    from app.worker import _Progress

    job_id = jobs.enqueue(session, "retrain", {}, actor=TESTER).id
    factory = make_session_factory(make_engine(settings.database_url))
    progress = _Progress(factory, job_id)
    progress(0.1, "fitting the model")
    progress(0.2)  # within the throttle: not stored
    progress(0.3, "weight posterior")  # a new stage: stored at once
    session.expire_all()
    job = jobs.get_job(session, job_id)
    assert (job.progress, job.stage) == (0.3, "weight posterior")
