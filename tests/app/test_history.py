"""The flights a retrain keeps for its next job (app.services.records.history): reused only while no
flight was written since, in the same database."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from datetime import timedelta
from pathlib import Path

import pandas as pd
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.config import Settings
from app.db import make_engine, make_session_factory
from app.services import audit
from app.services.jobs.retrain import enqueue_retrains, run_retrain
from app.services.records import history
from app.tables import Aircraft
from app.worker import run_pending
from tests.app.conftest import START, add_tail, inspect, serving, settings_for, settings_in

Reader = Callable[[], float]
WING = {"stress_factor": 1.5, "initial_crack_m": 0.002, "critical_crack_m": 0.04}


@pytest.fixture(autouse=True)
def _forgotten() -> Iterator[None]:
    history.forget_flights()
    yield
    history.forget_flights()


@pytest.fixture
def settings(database_url: str) -> Settings:
    """No worker thread in the app: its empty queue would forget the kept flights meanwhile."""
    return settings_for(database_url).model_copy(update={"run_worker": False})


@pytest.fixture
def reads(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """How many flights each read of the database returned (a reuse reads none)."""
    counts: list[int] = []
    stored = history.stored_flights

    def counted(session: Session, aircraft_ids: list[int]) -> pd.DataFrame:
        flights = stored(session, aircraft_ids)
        counts.append(len(flights))
        return flights

    monkeypatch.setattr(history, "stored_flights", counted)
    return counts


def _stress_total(settings: Settings) -> Reader:
    """A reader of the kept history's total recorded stress range over all aircraft."""
    factory = make_session_factory(make_engine(settings.database_url))

    def read() -> float:
        with factory() as session:
            ids = list(session.scalars(select(Aircraft.id).order_by(Aircraft.id)))
            loaded = history.load_history(
                session, ids, initial_crack_m=0.005, location_id=1, keep_flights=True
            )
            assert loaded is not None
            return float(loaded.data.loads.stress_range_mpa.sum())

    return read


def test_kept_flights_are_reused_until_a_flight_is_written(
    client: TestClient, settings: Settings, reads: list[int]
) -> None:
    add_tail(client, "N001", 10, stress=100.0)
    add_tail(client, "N002", 10, stress=50.0)
    read = _stress_total(settings)
    assert read() == 1500.0
    assert read() == 1500.0
    assert reads == [20]  # the second read reused the first

    later = (START + timedelta(days=30)).isoformat()
    one = [{"flight_id": "X1", "flown_at": later, "stress_range_mpa": 7.0, "mission": "M1"}]
    assert client.post("/aircraft/N002/flights", json=one).status_code == 201
    assert read() == 1507.0
    corrected = client.patch("/aircraft/N002/flights/X1", json={"stress_range_mpa": 9.0})
    assert corrected.status_code == 200, corrected.text
    assert read() == 1509.0
    assert client.delete("/aircraft/N002/flights/X1").status_code == 200
    assert read() == 1500.0
    assert reads == [20, 21, 21, 20]


def test_writes_of_other_records_keep_the_flights(
    client: TestClient, settings: Settings, reads: list[int]
) -> None:
    add_tail(client, "N001", 10, stress=100.0)
    read = _stress_total(settings)
    read()
    inspect(client, "N001", START + timedelta(days=2), 0.0051)
    assert client.put("/locations/wing", json=WING).status_code == 201
    read()
    assert reads == [10]
    assert client.delete("/aircraft/N001").status_code == 200
    with pytest.raises(AssertionError):  # no flights left: no history
        read()
    assert reads == [10, 0]


def _two_locations(client: TestClient) -> None:
    """One tail inspected at the default location and at `wing` (a tail never inspected would
    be read by the refill, not the retrain)."""
    add_tail(client, "LOW", 40, stress=100.0)
    at = (START + timedelta(days=10)).isoformat()
    assert client.put("/locations/wing", json=WING).status_code == 201
    for location, crack in (("default", 0.00501), ("wing", 0.0021)):
        body = {"inspection_id": f"I-{location}", "inspected_at": at, "crack_length_m": crack}
        answer = client.post("/aircraft/LOW/inspections", json={**body, "location": location})
        assert answer.status_code == 201, answer.text


def test_a_worker_reads_the_flights_once_for_a_retrain_of_two_locations(
    client: TestClient, settings: Settings, reads: list[int]
) -> None:
    _two_locations(client)
    factory = make_session_factory(make_engine(settings.database_url))
    with factory() as session:
        enqueue_retrains(session, {}, actor=audit.local("test"))
    assert run_pending(factory, settings, "test") == 2
    assert reads == [40]  # once: the first job's activation wrote no flights


def test_a_flight_written_between_two_locations_jobs_is_read(
    client: TestClient, settings: Settings, reads: list[int]
) -> None:
    _two_locations(client)
    factory = make_session_factory(make_engine(settings.database_url))
    with factory() as session:
        run_retrain(session, job_id=None, params={}, settings=settings, progress=_quiet)
    later = (START + timedelta(days=11)).isoformat()
    one = [{"flight_id": "X1", "flown_at": later, "stress_range_mpa": 7.0, "mission": "M1"}]
    assert client.post("/aircraft/LOW/flights", json=one).status_code == 201
    with factory() as session:
        params = {"location": "wing"}
        run_retrain(session, job_id=None, params=params, settings=settings, progress=_quiet)
    assert reads == [40, 41]


def _quiet(*_: object, **__: object) -> None:
    pass


def test_a_new_database_at_the_same_address_is_read_anew(tmp_path: Path) -> None:
    """Same address, aircraft ids and number of audit events (a test's, a restored one)."""
    settings = settings_in(tmp_path).model_copy(update={"run_worker": False})
    totals = []
    for stress in (100.0, 60.0):
        for stale in tmp_path.glob("fleetpinn.db*"):
            stale.unlink()
        with serving(settings) as client:
            add_tail(client, "N001", 10, stress=stress)
            totals.append(_stress_total(settings)())
    assert totals == [1000.0, 600.0]


def test_the_worker_forgets_the_flights_when_its_queue_runs_empty(
    client: TestClient, settings: Settings, reads: list[int]
) -> None:
    add_tail(client, "N001", 10, stress=100.0)
    inspect(client, "N001", START + timedelta(days=2), 0.0051)
    factory = make_session_factory(make_engine(settings.database_url))
    with factory() as session:
        enqueue_retrains(session, {}, actor=audit.local("test"))
    assert run_pending(factory, settings, "test") == 1
    assert reads == [10]
    _stress_total(settings)()
    assert reads == [10, 10]
