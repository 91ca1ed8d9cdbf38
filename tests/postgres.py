"""Throw-away PostgreSQL databases for the tests and benchmarks, on the server `make postgres`
starts (scripts/install-postgres.sh: Debian's PostgreSQL 15, role fleetpinn).

FLEETPINN_TEST_POSTGRES_URL names another server (any database on it; the role needs CREATEDB).
"""

from __future__ import annotations

import os
import time
import uuid
from functools import lru_cache

from psycopg.errors import InsufficientPrivilege, ObjectInUse
from sqlalchemy import create_engine, text
from sqlalchemy.engine import make_url
from sqlalchemy.exc import DBAPIError

from app import migrate

SERVER_URL = os.environ.get(
    "FLEETPINN_TEST_POSTGRES_URL",
    "postgresql+psycopg://fleetpinn:fleetpinn@127.0.0.1:5432/postgres",
)


@lru_cache
def unavailable() -> str | None:
    """Why PostgreSQL cannot be used here (None: it can), for a skip message."""
    try:
        engine = create_engine(SERVER_URL, connect_args={"connect_timeout": 5})
        with engine.connect() as connection:
            connection.execute(text("SELECT 1"))
        engine.dispose()
    except Exception as exc:
        reason = str(exc).splitlines()[0]
        return (
            f"PostgreSQL not reachable at {make_url(SERVER_URL).render_as_string()} ({reason}); "
            "`make postgres` (scripts/install-postgres.sh) installs and starts it"
        )
    return None


def url_of(name: str) -> str:
    """The URL of database `name` on the test server."""
    return make_url(SERVER_URL).set(database=name).render_as_string(hide_password=False)


def _admin(statement: str) -> None:
    # CREATE/DROP DATABASE cannot run inside a transaction block.
    engine = create_engine(SERVER_URL, isolation_level="AUTOCOMMIT")
    try:
        with engine.connect() as connection:
            connection.execute(text(statement))
    finally:
        engine.dispose()


# seconds a copy or a drop waits out an autovacuum worker on the database
AUTOVACUUM_WAIT_SECONDS = 30


def create_database(prefix: str = "fleetpinn_test", *, template: str | None = None) -> str:
    """A new empty database (or a copy of `template`) with a unique name; returns its name.  A
    copy needs the template to have no session: it waits out an autovacuum worker on it."""
    name = f"{prefix}_{uuid.uuid4().hex[:12]}"
    statement = f'CREATE DATABASE "{name}"' + (f' TEMPLATE "{template}"' if template else "")
    _admin_past_autovacuum(statement, ObjectInUse)
    return name


def drop_database(name: str) -> None:
    """Drop `name`, closing connections that a killed process may have left.  An autovacuum
    worker on it runs as the server's superuser, which FORCE may not terminate (insufficient
    privilege): the drop is tried again until the worker has left."""
    _admin_past_autovacuum(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)', InsufficientPrivilege)


def _admin_past_autovacuum(statement: str, busy: type[Exception]) -> None:
    """_admin(statement), tried again every 0.2 s while it fails with `busy` (the server's
    answer while an autovacuum worker holds the database), for AUTOVACUUM_WAIT_SECONDS."""
    deadline = time.monotonic() + AUTOVACUUM_WAIT_SECONDS
    while True:
        try:
            _admin(statement)
            return
        except DBAPIError as exc:
            if not isinstance(exc.orig, busy) or time.monotonic() > deadline:
                raise
            time.sleep(0.2)


def migrated_template(prefix: str = "fleetpinn_template") -> str:
    """A database migrated to head, to copy per test (CREATE DATABASE ... TEMPLATE is ~10x
    faster than migrating each one)."""
    name = create_database(prefix)
    migrate.upgrade(url_of(name))
    return name
