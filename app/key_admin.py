"""API keys administered from the command line (`fleetpinn keys`), on the database alone.

Each call migrates the database (a key may be the first thing stored) and opens its own
session.  Only the database's settings are read (app.settings_db), so `fleetpinn keys` starts
without the model stack (PyTorch, the forecast services): it took ~5 s, now well under 1 s.
"""

from __future__ import annotations

from typing import Any

from app import migrate as migrations
from app.db import make_engine, make_session_factory
from app.services import keys
from app.settings_db import DatabaseSettings


def create_key(
    role: str, name: str, *, replace: bool = False, settings: DatabaseSettings | None = None
) -> keys.NewKey:
    """Store a new API key (app.services.keys) and return it: the only time its secret shows."""
    url = (settings or DatabaseSettings()).database_url
    migrations.upgrade(url)
    with make_session_factory(make_engine(url))() as session:
        return keys.create_key(session, role=role, name=name, replace=replace)


def list_keys(settings: DatabaseSettings | None = None) -> list[dict[str, Any]]:
    """Every key without its secret: key_id, name, role, created_at, revoked_at."""
    url = (settings or DatabaseSettings()).database_url
    migrations.upgrade(url)
    with make_session_factory(make_engine(url))() as session:
        return [
            {
                "key_id": k.key_id,
                "name": k.name,
                "role": k.role,
                "created_at": k.created_at.isoformat(),
                "revoked_at": None if k.revoked_at is None else k.revoked_at.isoformat(),
            }
            for k in keys.list_keys(session)
        ]


def revoke_key(ident: str, settings: DatabaseSettings | None = None) -> dict[str, Any]:
    """Revoke the live key with this key_id or name."""
    url = (settings or DatabaseSettings()).database_url
    migrations.upgrade(url)
    with make_session_factory(make_engine(url))() as session:
        key = keys.revoke_key(session, ident)
        return {"key_id": key.key_id, "name": key.name, "role": key.role, "revoked": True}
