from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from sqlalchemy import inspect

from app import migrate
from app.db import Base, make_engine

TABLES = {
    "aircraft",
    "flights",
    "inspections",
    "model_versions",
    "jobs",
    "forecasts",
    "api_keys",
    "audit_events",
    "spectrum_blocks",
    "locations",
    "aircraft_locations",
}


def _tables(url: str) -> set[str]:
    engine = make_engine(url)
    try:
        return set(inspect(engine).get_table_names()) - {"alembic_version"}
    finally:
        engine.dispose()


def test_upgrade_from_empty_matches_the_models_and_round_trips(database_url: str) -> None:
    """On each backend (the PostgreSQL database starts as a copy of a migrated template)."""
    url = database_url
    migrate.upgrade(url)
    assert _tables(url) == TABLES
    engine = make_engine(url)
    with engine.connect() as connection:
        # The migrations build exactly the schema the ORM declares.
        assert compare_metadata(MigrationContext.configure(connection), Base.metadata) == []
    engine.dispose()
    migrate.downgrade(url, "base")
    assert _tables(url) == set()
    migrate.upgrade(url)
    assert _tables(url) == TABLES
