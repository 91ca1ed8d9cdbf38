"""A process killed during the upgrade leaves a SQLite database that the next upgrade brings to
head with every row (issue 42: a kill during 9c4d2e7f1a30's rebuild of flights left
_alembic_tmp_flights, and every later start failed "table _alembic_tmp_flights already
exists")."""

from __future__ import annotations

import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
from alembic.script import ScriptDirectory

from app import migrate
from tests.app.test_migrations import TABLES

BEFORE_REBUILD = "7a3e91c2d4f0"  # the revision before 9c4d2e7f1a30 rebuilds flights

# Runs the upgrade and ends the process (os._exit: no rollback, no cleanup, as SIGKILL) just
# before the first statement that starts with argv[1].
_KILLED_AT = """
import os, sys
from sqlalchemy import Engine, event
from app import migrate

def kill(_connection, _cursor, statement, *_args):
    if " ".join(statement.split()).upper().startswith(sys.argv[1]):
        os._exit(137)

event.listen(Engine, "before_cursor_execute", kill)
migrate.upgrade(sys.argv[2])
"""


def _head(url: str) -> str | None:
    return ScriptDirectory.from_config(migrate.alembic_config(url)).get_current_head()


def _database(path: Path) -> str:
    """A SQLite file at BEFORE_REBUILD with one tail of three flights."""
    url = f"sqlite:///{path}"
    migrate.upgrade(url, BEFORE_REBUILD)
    with sqlite3.connect(path) as connection:
        connection.execute(
            "INSERT INTO aircraft (id, tail, created_at) VALUES (1, 'K1', '2025-01-01 00:00:00')"
        )
        connection.executemany(
            "INSERT INTO flights (aircraft_id, flight_id, flown_at, stress_range_mpa)"
            " VALUES (1, ?, '2025-01-01 00:00:00', ?)",
            [("F1", 100.0), ("F2", 110.0), ("F3", 120.0)],
        )
    return url


def _state(path: Path) -> tuple[str, set[str], list[tuple[str, float]]]:
    """(version, tables, flights) as another process reads them after the kill."""
    with sqlite3.connect(path) as connection:
        version = connection.execute("SELECT version_num FROM alembic_version").fetchone()[0]
        tables = {
            row[0]
            for row in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'")
        }
        flights = connection.execute(
            "SELECT flight_id, stress_range_mpa FROM flights ORDER BY flight_id"
        ).fetchall()
    return version, tables - {"alembic_version", "sqlite_sequence"}, flights


FLIGHTS = [("F1", 100.0), ("F2", 110.0), ("F3", 120.0)]


@pytest.mark.parametrize(
    "statement",
    [
        "CREATE TABLE _ALEMBIC_TMP_FLIGHTS",  # the copy begun
        "INSERT INTO _ALEMBIC_TMP_FLIGHTS",  # the copy made, its rows not yet
        "DROP TABLE FLIGHTS",  # rows copied, the original still there
        "ALTER TABLE _ALEMBIC_TMP_FLIGHTS RENAME",  # the original dropped
        "CREATE TRIGGER",  # the rebuild done, its triggers not
        "UPDATE ALEMBIC_VERSION",  # the first step done, its version not written
        "CREATE TABLE LOCATIONS",  # a later revision
    ],
)
def test_an_upgrade_killed_anywhere_rolls_back_and_runs_again(
    tmp_path: Path, statement: str
) -> None:
    path = tmp_path / "killed.db"
    url = _database(path)
    before = _state(path)
    killed = subprocess.run(
        [sys.executable, "-c", _KILLED_AT, statement, url], capture_output=True, text=True
    )
    assert killed.returncode == 137, killed.stderr[-2000:]
    # one transaction: nothing of the upgrade is left, not even a step that had finished
    assert _state(path) == before == (BEFORE_REBUILD, before[1], FLIGHTS)
    migrate.upgrade(url)
    version, tables, flights = _state(path)
    assert (version, tables, flights) == (_head(url), TABLES, FLIGHTS)


def test_a_copy_left_by_an_earlier_kill_is_dropped_when_its_table_is_whole(
    tmp_path: Path,
) -> None:
    """Databases killed before the upgrade was one transaction hold the empty copy that
    CREATE TABLE committed alone; the next upgrade drops it and rebuilds."""
    path = tmp_path / "left.db"
    url = _database(path)
    with sqlite3.connect(path) as connection:
        connection.execute("CREATE TABLE _alembic_tmp_flights (id INTEGER PRIMARY KEY)")
        connection.execute("CREATE TABLE _alembic_tmp_gone (id INTEGER PRIMARY KEY)")
    migrate.upgrade(url)
    version, tables, flights = _state(path)
    assert version == _head(url) and flights == FLIGHTS
    # a copy whose table is gone may hold the only rows: it is left for a person to look at
    assert tables == TABLES | {"_alembic_tmp_gone"}
