"""Flights' references to aircraft and audit events, kept by triggers instead of foreign keys
(migration 9c4d2e7f1a30), on each backend: no orphan flight can be stored by the bulk path or
the ORM, a refused batch stores nothing, deleting an aircraft deletes its flights, and an audit
event or aircraft id that flights refer to cannot go away.  On PostgreSQL, an aircraft deleted
while an upload runs either refuses the upload or waits for it and deletes its flights too."""

from __future__ import annotations

import threading
import time
from typing import Any

import pandas as pd
import pytest
from sqlalchemy import Engine, delete, func, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.db import make_session_factory
from app.services import audit
from app.storage import bulk
from app.tables import Aircraft, AuditEvent, Flight
from tests.app.conftest import new_aircraft

TESTER = audit.local("test")


def _insert(session: Session, aircraft_ids: list[int], audit_id: int | None) -> None:
    """Flights F0, F1, ... of these aircraft through the upload's bulk path (COPY on PostgreSQL)."""
    store = bulk(session.connection())
    times = pd.Series(pd.date_range("2024-01-01", periods=len(aircraft_ids), tz="UTC"))
    store.insert(
        Flight.__table__,  # type: ignore[arg-type]
        {
            "aircraft_id": aircraft_ids,
            "flight_id": [f"F{i}" for i in range(len(aircraft_ids))],
            "flown_at": store.times(times),
            "stress_range_mpa": [100.0] * len(aircraft_ids),
            "mission": [None] * len(aircraft_ids),
            "audit_id": [audit_id] * len(aircraft_ids),
        },
    )


def _flights(engine: Engine) -> int:
    with engine.connect() as connection:
        return int(connection.scalar(select(func.count()).select_from(Flight)) or 0)


def test_a_batch_with_one_orphan_flight_stores_nothing(engine: Engine) -> None:
    with make_session_factory(engine)() as session:
        known = new_aircraft(session, "K1")
        event = audit.record(session, TESTER, "flights.ingest", "K1", {})
        _insert(session, [known, known], event)
        session.commit()
        assert _flights(engine) == 2
        for aircraft_ids, audit_id in (([known, known + 1, known], event), ([known], event + 1)):
            with pytest.raises(IntegrityError):
                _insert(session, aircraft_ids, audit_id)
            session.rollback()
    assert _flights(engine) == 2


def test_the_orm_cannot_store_or_move_a_flight_to_a_missing_aircraft(engine: Engine) -> None:
    with make_session_factory(engine)() as session:
        known = new_aircraft(session, "K1")
        session.add(
            Flight(
                aircraft_id=known + 7,
                flight_id="X",
                flown_at=pd.Timestamp.now("UTC"),
                stress_range_mpa=1.0,
            )
        )
        with pytest.raises(IntegrityError):
            session.commit()
        session.rollback()
        _insert(session, [known], None)
        session.commit()
        for values in ({"aircraft_id": known + 7}, {"audit_id": 12345}):
            with pytest.raises(IntegrityError):
                session.execute(update(Flight).values(**values))
            session.rollback()
    with engine.connect() as connection:
        assert connection.execute(select(Flight.aircraft_id, Flight.audit_id)).all() == [
            (known, None)
        ]


def test_deleting_an_aircraft_deletes_its_flights_only(engine: Engine) -> None:
    with make_session_factory(engine)() as session:
        gone, kept = new_aircraft(session, "GONE"), new_aircraft(session, "KEPT")
        _insert(session, [gone, kept, gone], None)
        session.commit()
        session.execute(delete(Aircraft).where(Aircraft.id == gone))
        session.commit()
        assert session.scalars(select(Flight.aircraft_id)).all() == [kept]


def test_referenced_audit_events_and_aircraft_ids_stay(engine: Engine) -> None:
    with make_session_factory(engine)() as session:
        known = new_aircraft(session, "K1")
        event = audit.record(session, TESTER, "flights.ingest", "K1", {})
        unused = audit.record(session, TESTER, "keys.create", "k", {})
        _insert(session, [known], event)
        session.commit()
        refused: list[Any] = [
            delete(AuditEvent).where(AuditEvent.id == event),
            update(AuditEvent).where(AuditEvent.id == event).values(id=event + 100),
            update(Aircraft).where(Aircraft.id == known).values(id=known + 100),
        ]
        for statement in refused:
            with pytest.raises(IntegrityError):
                session.execute(statement)
            session.rollback()
        session.execute(delete(AuditEvent).where(AuditEvent.id == unused))  # nothing refers to it
        session.execute(update(Aircraft).where(Aircraft.id == known).values(tail="K1B"))
        session.commit()
        assert session.scalar(select(func.count()).select_from(AuditEvent)) == 1
    assert _flights(engine) == 1


def _postgres_only(database_url: str) -> None:
    if not database_url.startswith("postgresql"):
        pytest.skip("SQLite serialises writers: no upload runs while an aircraft is deleted")


def _in_thread(work: Any) -> tuple[threading.Thread, list[BaseException]]:
    errors: list[BaseException] = []

    def run() -> None:
        try:
            work()
        except BaseException as exc:  # handed to the test's thread
            errors.append(exc)

    thread = threading.Thread(target=run)
    thread.start()
    return thread, errors


def test_an_aircraft_deleted_during_an_upload_waits_and_takes_its_flights(
    engine: Engine, database_url: str
) -> None:
    _postgres_only(database_url)
    factory = make_session_factory(engine)
    with factory() as uploader:
        aircraft_id = new_aircraft(uploader, "RACE")
        _insert(uploader, [aircraft_id] * 3, None)  # not committed: the aircraft rows are locked

        def delete_aircraft() -> None:
            with factory() as session:
                session.execute(delete(Aircraft).where(Aircraft.id == aircraft_id))
                session.commit()

        thread, errors = _in_thread(delete_aircraft)
        time.sleep(0.5)
        assert thread.is_alive(), "the deletion did not wait for the upload"
        uploader.commit()
        thread.join(10)
    assert not errors and not thread.is_alive()
    assert _flights(engine) == 0  # no orphan: the deletion saw the committed flights


def test_an_upload_refers_to_an_aircraft_deleted_meanwhile_is_refused(
    engine: Engine, database_url: str
) -> None:
    _postgres_only(database_url)
    factory = make_session_factory(engine)
    with factory() as deleter, factory() as uploader:
        aircraft_id = new_aircraft(deleter, "RACE")
        deleter.execute(delete(Aircraft).where(Aircraft.id == aircraft_id))  # not committed

        def upload() -> None:
            _insert(uploader, [aircraft_id] * 3, None)
            uploader.commit()

        thread, errors = _in_thread(upload)
        time.sleep(0.5)
        assert thread.is_alive(), "the upload did not wait for the deletion"
        deleter.commit()
        thread.join(10)
        uploader.rollback()
    assert len(errors) == 1 and isinstance(errors[0], IntegrityError), errors
    assert _flights(engine) == 0
