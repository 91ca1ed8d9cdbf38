"""The queue's admission (issue 42: 50 concurrent retrains queued 50 jobs, ~100 h of worker
time): one queued retrain per location, at most max_queued_jobs queued, 429 past it."""

from __future__ import annotations

from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app import migrate
from app.config import Settings, get_settings
from app.db import make_engine, make_session_factory
from app.errors import QueueFull
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


def _queued(session: Session) -> int:
    return session.scalar(select(func.count()).select_from(Job).where(Job.status == "queued")) or 0


def test_a_location_has_at_most_one_queued_retrain(session: Session) -> None:
    first = jobs.enqueue(session, "retrain", {"epochs": 5}, actor=TESTER)
    assert jobs.already_queued(session) == []
    again = jobs.enqueue(session, "retrain", {"epochs": 9}, actor=TESTER)
    assert again.id == first.id and again.params == {"epochs": 5}  # its options stand
    assert jobs.already_queued(session) == [first.id]
    wing = jobs.enqueue(session, "retrain", {"location": "wing"}, actor=TESTER)
    assert wing.id != first.id
    # once it runs, the location may queue the next
    assert jobs.claim_next(session, "w") == first.id
    assert jobs.enqueue(session, "retrain", {}, actor=TESTER).id not in (first.id, wing.id)
    assert _queued(session) == 2


def test_past_the_queue_limit_nothing_is_queued(session: Session) -> None:
    session.info[jobs.QUEUE_LIMIT] = 3
    for _ in range(3):
        jobs.enqueue(session, "forecast-batch", {}, actor=TESTER)
    with pytest.raises(
        QueueFull, match=r"3 jobs are queued, at most 3 \(FLEETPINN_MAX_QUEUED_JOBS\)"
    ):
        jobs.enqueue(session, "forecast-batch", {}, actor=TESTER)
    with pytest.raises(QueueFull):
        jobs.enqueue(session, "retrain", {}, actor=TESTER)
    assert _queued(session) == 3
    assert jobs.claim_next(session, "w") is not None  # a running job leaves room
    jobs.enqueue(session, "retrain", {}, actor=TESTER)
    assert _queued(session) == 3


@pytest.fixture
def client(settings: Settings) -> Iterator[TestClient]:
    app = create_app()
    quiet = settings.model_copy(update={"run_worker": False, "max_queued_jobs": 2})
    app.dependency_overrides[get_settings] = lambda: quiet
    with TestClient(app) as test_client:
        test_client.headers.update(bearer(new_key(app, "write")))
        yield test_client


def test_fifty_concurrent_retrains_queue_one_job(client: TestClient, session: Session) -> None:
    with ThreadPoolExecutor(8) as pool:
        answers = list(pool.map(lambda _: client.post("/models/retrain", json={}), range(50)))
    assert {a.status_code for a in answers} == {202}
    job_ids = {a.json()["job_id"] for a in answers}
    assert len(job_ids) == 1
    (job_id,) = job_ids
    told = [a.json()["already_queued"] for a in answers]
    assert told.count([]) == 1 and told.count([job_id]) == 49
    assert _queued(session) == 1


def test_a_full_queue_answers_429_with_the_reason(client: TestClient, session: Session) -> None:
    jobs.enqueue(session, "forecast-batch", {}, actor=TESTER)
    jobs.enqueue(session, "forecast-batch", {}, actor=TESTER)
    answer = client.post("/models/retrain", json={"epochs": 3})
    assert answer.status_code == 429
    assert answer.headers["retry-after"] == "60"
    assert "2 jobs are queued, at most 2 (FLEETPINN_MAX_QUEUED_JOBS)" in answer.json()["detail"]
    assert _queued(session) == 2
    assert client.get("/openapi.json").json()["paths"]["/models/retrain"]["post"]["responses"][
        "429"
    ]
