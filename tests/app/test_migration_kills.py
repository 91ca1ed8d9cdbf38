"""A process killed during the upgrade leaves a database (SQLite or PostgreSQL) that the next
upgrade brings to head with every row (issue 42: a kill during 9c4d2e7f1a30's rebuild of flights left
_alembic_tmp_flights, and every later start failed "table _alembic_tmp_flights already
exists")."""

from __future__ import annotations

import sqlite3
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

import pytest
from alembic.script import ScriptDirectory
from sqlalchemy import inspect, text

from app import migrate
from app.db import make_engine
from tests.app.test_migrations import TABLES

BEFORE_REBUILD = "7a3e91c2d4f0"  # the revision before 9c4d2e7f1a30 rebuilds flights

# Runs the upgrade and ends the process (os._exit: no rollback, no cleanup, as SIGKILL) just
# before the first statement that starts with argv[1].
_KILLED_AT = """
import os, sys
from sqlalchemy import Engine, event
from app import migrate
from app.db import make_engine

def kill(_connection, _cursor, statement, *_args):
    if " ".join(statement.split()).upper().startswith(sys.argv[1]):
        os._exit(137)

event.listen(Engine, "before_cursor_execute", kill)
migrate.upgrade(sys.argv[2])
"""


def _head(url: str) -> str | None:
    return ScriptDirectory.from_config(migrate.alembic_config(url)).get_current_head()


def _at_before_rebuild(url: str) -> None:
    """The test's database (migrated to head) taken back to BEFORE_REBUILD, with one tail of
    three flights."""
    migrate.downgrade(url, BEFORE_REBUILD)
    engine = make_engine(url)
    try:
        with engine.begin() as connection:
            connection.execute(
                text("INSERT INTO aircraft (id, tail, created_at) VALUES (1, 'K1', :at)"),
                {"at": datetime(2025, 1, 1, tzinfo=UTC)},
            )
            connection.execute(
                text(
                    "INSERT INTO flights (aircraft_id, flight_id, flown_at, stress_range_mpa)"
                    " VALUES (1, :id, :at, :stress)"
                ),
                [
                    {"id": flight, "at": datetime(2025, 1, 1, tzinfo=UTC), "stress": stress}
                    for flight, stress in FLIGHTS
                ],
            )
    finally:
        engine.dispose()


def _state(url: str) -> tuple[str, set[str], list[tuple[str, float]]]:
    """(version, tables, flights) as another process reads them after the kill."""
    engine = make_engine(url)
    try:
        with engine.connect() as connection:
            version = connection.execute(text("SELECT version_num FROM alembic_version")).scalar()
            tables = set(inspect(connection).get_table_names())
            flights = connection.execute(
                text("SELECT flight_id, stress_range_mpa FROM flights ORDER BY flight_id")
            ).all()
    finally:
        engine.dispose()
    return str(version), tables - {"alembic_version"}, [tuple(row) for row in flights]


FLIGHTS = [("F1", 100.0), ("F2", 110.0), ("F3", 120.0)]
# Statements to die before, in the order the upgrade reaches them: SQLite rebuilds flights by
# copying it (batch mode), PostgreSQL alters it in place.
_REVISION_STEPS = [
    "UPDATE ALEMBIC_VERSION",  # the first step done, its version not written
    "CREATE TABLE LOCATIONS",  # a later revision
]
SQLITE_KILLS = [
    "CREATE TABLE _ALEMBIC_TMP_FLIGHTS",  # the copy begun
    "INSERT INTO _ALEMBIC_TMP_FLIGHTS",  # the copy made, its rows not yet
    "DROP TABLE FLIGHTS",  # rows copied, the original still there
    "ALTER TABLE _ALEMBIC_TMP_FLIGHTS RENAME",  # the original dropped
    "CREATE TRIGGER",  # the rebuild done, its triggers not
    *_REVISION_STEPS,
]
POSTGRESQL_KILLS = [
    "ALTER TABLE FLIGHTS DROP CONSTRAINT",  # the foreign keys dropped one by one
    "CREATE FUNCTION",  # their triggers not yet made
    *_REVISION_STEPS,
]


@pytest.mark.parametrize(
    ("database_url", "statement"),
    [("sqlite", s) for s in SQLITE_KILLS] + [("postgresql", s) for s in POSTGRESQL_KILLS],
    indirect=["database_url"],
)
def test_an_upgrade_killed_anywhere_rolls_back_and_runs_again(
    database_url: str, statement: str
) -> None:
    _at_before_rebuild(database_url)
    before = _state(database_url)
    assert before[0] == BEFORE_REBUILD and before[2] == FLIGHTS
    killed = subprocess.run(
        [sys.executable, "-c", _KILLED_AT, statement, database_url],
        capture_output=True,
        text=True,
    )
    assert killed.returncode == 137, killed.stderr[-2000:]
    # one transaction: nothing of the upgrade is left, not even a step that had finished
    assert _state(database_url) == before
    migrate.upgrade(database_url)
    assert _state(database_url) == (_head(database_url), TABLES, FLIGHTS)


def test_a_copy_left_by_an_earlier_kill_is_dropped_when_its_table_is_whole(
    tmp_path: Path,
) -> None:
    """Databases killed before the upgrade was one transaction hold the empty copy that
    CREATE TABLE committed alone; the next upgrade drops it and rebuilds."""
    path = tmp_path / "left.db"
    url = f"sqlite:///{path}"
    migrate.upgrade(url)
    _at_before_rebuild(url)
    with sqlite3.connect(path) as connection:
        connection.execute("CREATE TABLE _alembic_tmp_flights (id INTEGER PRIMARY KEY)")
        connection.execute("CREATE TABLE _alembic_tmp_gone (id INTEGER PRIMARY KEY)")
    migrate.upgrade(url)
    version, tables, flights = _state(url)
    assert version == _head(url) and flights == FLIGHTS
    # a copy whose table is gone may hold the only rows: it is left for a person to look at
    assert tables == TABLES | {"_alembic_tmp_gone"}
