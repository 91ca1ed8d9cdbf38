"""Alembic environment: the URL comes from the caller (app.migrate) or from the settings
(app.settings_db: the database alone, so that `fleetpinn keys` starts without the model stack)."""

from __future__ import annotations

from typing import Any

from alembic import context

from app.db import Base, make_engine
from app.migrate import drop_unfinished_copies, transactional_sqlite
from app.settings_db import DatabaseSettings
from app.tables import UTCDateTime  # importing app.tables registers the tables on Base.metadata

config = context.config
target_metadata = Base.metadata


def database_url() -> str:
    return config.get_main_option("sqlalchemy.url") or DatabaseSettings().database_url


def render_item(kind: str, obj: Any, _context: Any) -> str | bool:
    # Revisions must not import app code: UTCDateTime is a DateTime(timezone=True) in the schema.
    if kind == "type" and isinstance(obj, UTCDateTime):
        return "sa.DateTime(timezone=True)"
    return False


def run_migrations_offline() -> None:
    context.configure(
        url=database_url(),
        target_metadata=target_metadata,
        literal_binds=True,
        render_as_batch=True,
        render_item=render_item,
    )
    with context.begin_transaction():
        context.run_migrations()


def run_migrations_online() -> None:
    """The whole upgrade in one transaction on either database (app.migrate): a process killed
    during it leaves the schema and the version as they were, and the next start runs it all."""
    engine = make_engine(database_url())
    sqlite = engine.dialect.name == "sqlite"
    if sqlite:
        transactional_sqlite(engine)
    with engine.connect() as connection:
        # Batch mode: SQLite alters tables by copying them.
        context.configure(
            connection=connection,
            target_metadata=target_metadata,
            render_as_batch=True,
            render_item=render_item,
            transactional_ddl=True,
        )
        with context.begin_transaction():
            if sqlite:
                drop_unfinished_copies(connection)
            context.run_migrations()
    engine.dispose()


if context.is_offline_mode():
    run_migrations_offline()
else:
    run_migrations_online()
