"""A database built once per module and copied for each test that changes it: such tests start
from the same stored fleet and trained models without training them again (a retrain and its
uploads took ~3 s of each test's ~3.5).

    stored_database, fleet = copied_for_each_test("fleet", _store_fleet)

SQLite: the file copied with SQLite's online backup; PostgreSQL: CREATE DATABASE ... TEMPLATE.
The source must be closed (no engine of it open) when copied.
"""

from __future__ import annotations

import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy.engine import make_url

from app.config import Settings, get_settings
from tests import postgres
from tests.app.conftest import copy_sqlite, serving, settings_for


@contextmanager
def copy_of(database_url: str, folder: Path) -> Iterator[str]:
    """The URL of a fresh copy of the database at database_url (a PostgreSQL copy is dropped
    afterwards)."""
    if database_url.startswith("sqlite"):
        target = folder / f"copy-{uuid.uuid4().hex[:8]}.db"
        copy_sqlite(database_url.removeprefix("sqlite:///"), target)
        yield f"sqlite:///{target}"
        return
    template = make_url(database_url).database
    assert template is not None
    name = postgres.create_database(template=template)
    try:
        yield postgres.url_of(name)
    finally:
        postgres.drop_database(name)


@contextmanager
def serving_copy(database_url: str, folder: Path) -> Iterator[TestClient]:
    """The app serving a fresh copy of the database at database_url (the tests' settings)."""
    with copy_of(database_url, folder) as url, serving(settings_for(url)) as client:
        yield client


def served_settings(client: TestClient) -> Settings:
    """The settings the app of `client` is served with (serving's override)."""
    override = client.app.dependency_overrides[get_settings]  # type: ignore[attr-defined]
    settings: Settings = override()
    return settings


def copied_for_each_test(name: str, build: Callable[[TestClient], object]) -> tuple[Any, Any]:
    """Two fixtures, to assign at module level: `stored_database` (module scope, each backend:
    module_database_url filled by `build` through the app, then closed) and `name`, which
    serves each test a fresh copy of it (its docstring is build's)."""

    @pytest.fixture(scope="module")
    def stored_database(module_database_url: str) -> str:
        with serving(settings_for(module_database_url)) as client:
            build(client)
        return module_database_url

    def served(stored_database: str, tmp_path: Path) -> Iterator[TestClient]:
        with serving_copy(stored_database, tmp_path) as client:
            yield client

    served.__doc__ = build.__doc__
    return stored_database, pytest.fixture(name=name)(served)
