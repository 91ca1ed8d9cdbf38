"""Apply the Alembic migrations programmatically (service start, `fleetpinn migrate`, tests),
each upgrade one transaction on SQLite as on PostgreSQL (migrations/env.py), so that a process
killed during it leaves the schema as it was before."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from alembic import command
from alembic.config import Config
from sqlalchemy import Connection, Engine, event, inspect

_log = logging.getLogger("fleetpinn.migrate")
# A batch rebuild copies table x into this and renames the copy (Alembic's batch mode).
_BATCH_COPY = "_alembic_tmp_"


def migrations_dir() -> Path:
    """migrations/ beside the package (source checkout, editable install, the Docker image)."""
    for root in (Path(__file__).resolve().parents[1], Path.cwd()):
        if (root / "migrations" / "env.py").is_file():
            return root / "migrations"
    raise FileNotFoundError("migrations/ not found beside the app package or in the working dir")


def alembic_config(database_url: str) -> Config:
    config = Config()
    config.set_main_option("script_location", str(migrations_dir()))
    # ConfigParser interpolation: a literal % in a URL (escaped password) must be doubled.
    config.set_main_option("sqlalchemy.url", database_url.replace("%", "%%"))
    return config


def upgrade(database_url: str, revision: str = "head") -> None:
    command.upgrade(alembic_config(database_url), revision)


def downgrade(database_url: str, revision: str) -> None:
    command.downgrade(alembic_config(database_url), revision)


def transactional_sqlite(engine: Engine) -> None:
    """Run a SQLite engine's DDL inside its transactions.  pysqlite begins a transaction only
    before INSERT, UPDATE or DELETE, so a batch rebuild's CREATE TABLE _alembic_tmp_x committed
    alone, and a process killed after it left the copy behind: every later start failed "table
    _alembic_tmp_flights already exists" (issue 42).  The driver's own handling is switched off
    and SQLAlchemy's begin emits BEGIN IMMEDIATE (its documented pysqlite recipe), which also
    takes the write lock first, so two processes starting at once migrate one after the other.
    """

    def driver_autocommit(dbapi_connection: Any, _record: Any) -> None:
        dbapi_connection.isolation_level = None

    def begin_immediate(connection: Connection) -> None:
        connection.exec_driver_sql("BEGIN IMMEDIATE")

    event.listen(engine, "connect", driver_autocommit)
    event.listen(engine, "begin", begin_immediate)


def drop_unfinished_copies(connection: Connection) -> list[str]:
    """Drop each _alembic_tmp_x whose table x still exists: a copy that an upgrade killed
    before this module made SQLite's DDL transactional left behind (x itself is whole: its
    rows are dropped only in the transaction that renames the copy).  Returns the dropped
    names."""
    tables = set(inspect(connection).get_table_names())
    dropped = sorted(
        name
        for name in tables
        if name.startswith(_BATCH_COPY) and name.removeprefix(_BATCH_COPY) in tables
    )
    for name in dropped:
        _log.warning(
            "dropping %s, left by a migration that was stopped (%s is whole)",
            name,
            name.removeprefix(_BATCH_COPY),
        )
        connection.exec_driver_sql(f'DROP TABLE "{name}"')
    return dropped
