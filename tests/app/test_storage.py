"""app.storage's bulk paths on each backend (SQLite executemany, PostgreSQL binary COPY), and
the job queue's claim under concurrent workers."""

from __future__ import annotations

import threading
from collections import Counter

import numpy as np
import pandas as pd
import pytest
from sqlalchemy import Engine, String, func, select, type_coerce
from sqlalchemy.exc import IntegrityError

from app.db import make_session_factory
from app.services import audit
from app.services.jobs import queue as jobs
from app.storage import bulk, parse_utc
from app.tables import Flight, Inspection, Job
from tests.app.conftest import new_aircraft

TESTER = audit.local("test")


def _flight_columns(aircraft_id: int, store, times: pd.Series, ids: list[str]) -> dict:
    return {
        "aircraft_id": [aircraft_id] * len(ids),
        "flight_id": ids,
        "flown_at": store.times(times),
        "stress_range_mpa": [0.1 + i / 3 for i in range(len(ids))],
        "mission": [None if i % 2 else "M\t1" for i in range(len(ids))],
    }


def test_bulk_insert_round_trips_times_text_floats_and_nulls(engine: Engine) -> None:
    times = pd.Series(
        pd.to_datetime(
            ["2024-01-01T00:00:00.000001Z", "1999-12-31T23:59:59.999999Z", "2030-06-01T12:00:00Z"],
            format="ISO8601",
        )
    )
    # Characters a text protocol would have to escape, and more than ASCII.
    ids = ["F\t1", "F\\2\nx", "Fé3"]
    with make_session_factory(engine)() as session:
        aircraft_id = new_aircraft(session, "RT")
        store = bulk(session.connection())
        columns = _flight_columns(aircraft_id, store, times, ids)
        store.insert(Flight.__table__, columns)  # type: ignore[arg-type]
        session.commit()
        query = (
            select(
                Flight.flight_id,
                type_coerce(Flight.flown_at, String),
                Flight.stress_range_mpa,
                Flight.mission,
            )
            .where(Flight.aircraft_id == aircraft_id)
            .order_by(Flight.id)
        )
        frame = bulk(session.connection()).frame(query, ["flight_id", "flown_at", "stress", "m"])
    assert frame["flight_id"].tolist() == ids
    assert parse_utc(frame["flown_at"]).tolist() == times.tolist()
    assert frame["stress"].tolist() == columns["stress_range_mpa"]  # exact, not rounded
    assert frame["m"].isna().tolist() == [False, True, False]
    assert frame["m"][0] == frame["m"][2] == "M\t1"


def test_a_duplicate_key_is_an_integrity_error_and_rolls_back_the_batch(engine: Engine) -> None:
    times = pd.Series(pd.to_datetime(["2024-01-01", "2024-01-02", "2024-01-03"], utc=True))
    with make_session_factory(engine)() as session:
        aircraft_id = new_aircraft(session, "DUP")
        store = bulk(session.connection())
        store.insert(Flight.__table__, _flight_columns(aircraft_id, store, times[:1], ["F1"]))  # type: ignore[arg-type]
        session.commit()
        store = bulk(session.connection())
        batch = _flight_columns(aircraft_id, store, times, ["F2", "F3", "F1"])
        with pytest.raises(IntegrityError):
            store.insert(Flight.__table__, batch)  # type: ignore[arg-type]
        session.rollback()
        assert session.scalar(select(func.count()).select_from(Flight)) == 1


def test_bulk_insert_of_inspection_flags_and_missing_values(engine: Engine) -> None:
    with make_session_factory(engine)() as session:
        aircraft_id = new_aircraft(session, "INS")
        store = bulk(session.connection())
        times = pd.Series(pd.to_datetime(["2024-01-01", "2024-02-01"], utc=True))
        columns = {
            "aircraft_id": [aircraft_id, aircraft_id],
            "inspection_id": ["I1", "I2"],
            "inspected_at": store.times(times),
            "crack_length_m": [0.006, None],
            "detected": [True, False],
            "detection_threshold_m": [None, 0.002],
            "repaired": [False, False],
            "flagged": [False, True],
        }
        store.insert(Inspection.__table__, columns)  # type: ignore[arg-type]
        session.commit()
        rows = session.execute(
            select(Inspection.crack_length_m, Inspection.detected, Inspection.inspected_at)
            .where(Inspection.aircraft_id == aircraft_id)
            .order_by(Inspection.inspection_id)
        ).all()
    assert [(r[0], r[1]) for r in rows] == [(0.006, True), (None, False)]
    assert [r[2] for r in rows] == list(times.dt.to_pydatetime())


def test_concurrent_workers_claim_every_job_exactly_once(engine: Engine) -> None:
    factory = make_session_factory(engine)
    with factory() as session:
        # batch forecasts: a location has one queued retrain at most (app.services.jobs.queue)
        queued = [jobs.enqueue(session, "forecast-batch", {}, actor=TESTER).id for _ in range(24)]
    claimed: list[str] = []
    lock = threading.Lock()
    start = threading.Barrier(4)

    def claim(name: str) -> None:
        start.wait()
        misses = 0
        while misses < 20:  # a SQLite claimer that loses a race sees None; try again
            with factory() as session:
                job_id = jobs.claim_next(session, name)
            if job_id is None:
                misses += 1
                continue
            with lock:
                claimed.append(job_id)

    threads = [threading.Thread(target=claim, args=(f"w{i}",)) for i in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert Counter(claimed) == Counter(queued)  # every job once, none twice
    with factory() as session:
        attempts = session.scalars(select(Job.attempts)).all()
    assert np.all(np.array(attempts) == 1)
