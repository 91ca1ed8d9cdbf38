"""API test fixtures: a real database per test, the app with get_settings overridden, and a
client that sends an admin key (new_key() makes keys of other roles).

`database_url` (and so `settings` and `client`) is parametrized over both backends: a SQLite
file and a fresh PostgreSQL database, each copied from a migrated template (tests.postgres; the
PostgreSQL tests skip, saying why, where `make postgres` could not install and start the
server).  SQLITE_ONLY narrows a test whose check lies above the storage to SQLite.
"""

from __future__ import annotations

import sqlite3
import threading
from collections.abc import Iterator
from contextlib import closing, contextmanager
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import torch
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy import Engine, event
from sqlalchemy.orm import Session, sessionmaker

from app import migrate
from app.config import Settings, get_settings
from app.db import make_engine, make_session_factory
from app.local_server import wait_for_job
from app.main import create_app
from app.services import audit, keys
from app.services.forecasts import forecast_answers
from app.services.ranking import order as ranking
from app.services.ranking import ranking_answers
from app.services.records import ingest, locations
from app.tables import Aircraft
from model.fleet import DISCREPANCY_20PCT, FleetConfig, generate_fleet, inspect_at
from tests import postgres

torch.set_num_threads(1)

START = datetime(2024, 1, 1, tzinfo=UTC)
# "Today" of the tests: the first day of their flights, so horizons count from the last flight
# (a test of the as-of date asks for its own).
AS_OF = START.date()


BACKENDS = ("sqlite", "postgresql")
# Where what a test checks lies above the storage (a browser's rendering, the client CLI, the
# promotion gate's verdict), it runs on SQLite alone: each backend's storage, queries, jobs and
# races are tested by the modules that store them, on both.
SQLITE_ONLY = pytest.mark.parametrize("database_url", ["sqlite"], indirect=True)
SQLITE_ONLY_SERVER = pytest.mark.parametrize(
    "module_database_url", ["sqlite"], indirect=True, scope="module"
)


def settings_in(folder: Path) -> Settings:
    """A SQLite file in `folder`."""
    return settings_for(f"sqlite:///{folder / 'fleetpinn.db'}")


def settings_for(database_url: str) -> Settings:
    """The physics kernel trains instantly, so job tests stay fast.  No answers made ahead
    (app.services.forecasts.answers_ahead; tests/app/test_answers_ahead.py turns them on): that thread
    would make forecasts beside a test that counts a request's own."""
    return Settings(
        database_url=database_url,
        kernel="physics",
        worker_poll_seconds=0.05,
        as_of=AS_OF,
        answers_ahead=False,
    )


def new_key(app: FastAPI, role: str, name: str | None = None) -> str:
    """A fresh API key of `role` in the app's database (the app has started)."""
    with app.state.session_factory() as session:
        return keys.create_key(session, role=role, name=name or f"test-{role}", replace=True).key


def bearer(key: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {key}"}


@contextmanager
def serving(settings: Settings) -> Iterator[TestClient]:
    """The app (lifespan included) with get_settings overridden by `settings`; the client sends
    an admin key."""
    app = create_app()
    app.dependency_overrides[get_settings] = lambda: settings
    with TestClient(app) as test_client:
        test_client.headers.update(bearer(new_key(app, "admin")))
        yield test_client


@pytest.fixture(scope="session")
def postgres_template() -> Iterator[str]:
    """A PostgreSQL database migrated to head, copied by each PostgreSQL test."""
    reason = postgres.unavailable()
    if reason:
        pytest.skip(reason)
    name = postgres.migrated_template()
    yield name
    postgres.drop_database(name)


@pytest.fixture(scope="session")
def sqlite_template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A SQLite file migrated to head, copied by each SQLite test (as postgres_template: the
    migrations took ~0.25 s a test)."""
    path = tmp_path_factory.mktemp("template") / "fleetpinn.db"
    migrate.upgrade(f"sqlite:///{path}")
    return path


def copy_sqlite(source: Path | str, target: Path) -> None:
    """`source` copied to `target` with SQLite's online backup (its write-ahead log too)."""
    with closing(sqlite3.connect(source)) as read, closing(sqlite3.connect(target)) as write:
        read.backup(write)


@pytest.fixture(params=BACKENDS)
def database_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    """A SQLite file in tmp_path, or a fresh PostgreSQL database (dropped afterwards), each a
    copy of a database migrated to head."""
    yield from _backend_url(request, tmp_path)


@pytest.fixture(scope="module", params=BACKENDS)
def module_database_url(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[str]:
    """database_url shared by a module's tests (end-to-end servers)."""
    yield from _backend_url(request, tmp_path_factory.mktemp("db"))


def _backend_url(request: pytest.FixtureRequest, folder: Path) -> Iterator[str]:
    """The database of request.param: a SQLite file in folder, or a fresh PostgreSQL database,
    dropped afterwards; each copied from its migrated template."""
    if request.param == "sqlite":
        copy_sqlite(request.getfixturevalue("sqlite_template"), folder / "fleetpinn.db")
        yield f"sqlite:///{folder / 'fleetpinn.db'}"
        return
    name = postgres.create_database(template=request.getfixturevalue("postgres_template"))
    try:
        yield postgres.url_of(name)
    finally:
        postgres.drop_database(name)


@pytest.fixture
def engine(database_url: str) -> Iterator[Engine]:
    """An engine on the test's database, migrated (storage tests that bypass the API)."""
    migrate.upgrade(database_url)
    engine = make_engine(database_url)
    yield engine
    engine.dispose()


def new_aircraft(session: Session, tail: str) -> int:
    """Store a tail directly; its id."""
    aircraft = Aircraft(tail=tail)
    session.add(aircraft)
    session.commit()
    return aircraft.id


@pytest.fixture
def settings(database_url: str) -> Settings:
    return settings_for(database_url)


@pytest.fixture
def client(settings: Settings) -> Iterator[TestClient]:
    with serving(settings) as test_client:
        yield test_client


def flights(
    n: int, *, stress: float | list[float] = 100.0, start: datetime = START, per_day: int = 4
) -> list[dict[str, Any]]:
    """n flights, per_day a day from `start`, ids F0001..; a list of stresses is cycled."""
    cycle = stress if isinstance(stress, list) else [stress]
    step = timedelta(days=1) / per_day
    return [
        {
            "flight_id": f"F{i + 1:04d}",
            "flown_at": (start + i * step).isoformat(),
            "stress_range_mpa": cycle[i % len(cycle)],
            "mission": "M1",
        }
        for i in range(n)
    ]


def add_tail(client: TestClient, tail: str, n: int, **kwargs: Any) -> None:
    assert client.put(f"/aircraft/{tail}").status_code in (200, 201)
    answer = client.post(f"/aircraft/{tail}/flights", json=flights(n, **kwargs))
    assert answer.status_code == 201, answer.text


def retrained(client: TestClient, **body: Any) -> dict[str, Any]:
    """POST /models/retrain with this body, waited for: its job, which must have succeeded."""
    job = wait_for_job(client, client.post("/models/retrain", json=body).json()["job_id"])
    assert job["status"] == "succeeded", job["error"]
    return job


def inspect(client: TestClient, tail: str, at: datetime, crack_length_m: float) -> None:
    body = {
        "inspection_id": f"I-{at:%Y%m%d%H%M}",
        "inspected_at": at.isoformat(),
        "crack_length_m": crack_length_m,
    }
    answer = client.post(f"/aircraft/{tail}/inspections", json=body)
    assert answer.status_code == 201, answer.text


def later_flights(client: TestClient, tail: str) -> None:
    """Flights 41-44 of `flights` at 300 MPa, after a tail added with 40: an ingest that
    advances its rows."""
    answer = client.post(f"/aircraft/{tail}/flights", json=flights(44, stress=300.0)[40:])
    assert answer.status_code == 201, answer.text


def repair(client: TestClient, tail: str) -> None:
    """A repair of the tail on day 10: 5.2 mm found, 1 mm left."""
    body = {
        "inspection_id": "R1",
        "inspected_at": (START + timedelta(days=10, hours=2)).isoformat(),
        "crack_length_m": 0.0052,
        "repaired": True,
        "crack_after_repair_m": 0.001,
    }
    answer = client.post(f"/aircraft/{tail}/inspections", json=body)
    assert answer.status_code == 201, answer.text


@contextmanager
def statements(client: TestClient) -> Iterator[list[str]]:
    """The SQL statements (lower case) the app's engine runs meanwhile for requests (not the
    worker's or the answers made ahead: their threads are named fleetpinn-...)."""
    seen: list[str] = []
    engine = client.app.state.engine  # type: ignore[attr-defined]

    def record(*args: Any) -> None:
        if not threading.current_thread().name.startswith("fleetpinn-"):
            seen.append(args[2].lower())

    event.listen(engine, "before_cursor_execute", record)
    try:
        yield seen
    finally:
        event.remove(engine, "before_cursor_execute", record)


def forget_kept_answers() -> None:
    """What this process keeps between requests (forecast and ranking answers, fleet orders)
    dropped, so the next answer is made from scratch."""
    forecast_answers._ANSWERS.clear()
    ranking._ORDERED.clear()
    ranking_answers._ANSWERS.clear()


def stored_two_location_fleet(
    settings: Settings, location: str, entry: dict[str, Any], crack_scale: float = 1.0
) -> sessionmaker[Session]:
    """Six tails of the thesis fleet (growth scatter, the 20 % discrepancy) over two years,
    stored through the services in a migrated database: each inspected at the end of both
    years at the default location and at `location` (catalogue `entry`), whose measured
    cracks are the default's times crack_scale."""
    fleet = generate_fleet(
        FleetConfig(
            aircraft_per_mix=2, years=2, discrepancy=DISCREPANCY_20PCT, growth_scatter=0.25, seed=0
        )
    )
    per_year = fleet.config.flights_per_year
    sample = inspect_at(fleet, np.arange(fleet.size), np.array([per_year, 2 * per_year]), 0.04)
    found = fleet.inspections_frame(sample)
    other = found.assign(
        inspection_id=found["inspection_id"].astype(str) + f"-{location}",
        crack_length_m=found["crack_length_m"] * crack_scale,
        location=location,
    )
    actor = audit.local("test")
    migrate.upgrade(settings.database_url)
    factory = make_session_factory(make_engine(settings.database_url))
    with factory() as session:
        ingest.ingest_flights(
            session,
            fleet.flights_frame(),
            source="t",
            create_tails=True,
            actor=actor,
            settings=settings,
        )
        locations.put_location(session, location, entry, actor=actor, settings=settings)
        ingest.ingest_inspections(
            session,
            pd.concat([found, other], ignore_index=True),
            source="t",
            actor=actor,
            settings=settings,
        )
    return factory
