"""Where the database is: the one setting every command needs, readable without the model stack.

app.config.Settings extends DatabaseSettings with everything else; commands that only touch the
database (`fleetpinn keys`, Alembic's environment) read this part alone, so they start without
importing PyTorch (app.config validates the model's settings against model/'s registries).
"""

from __future__ import annotations

from pydantic import field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict


class DatabaseSettings(BaseSettings):
    """FLEETPINN_DATABASE_URL; an unknown backend fails at start-up."""

    model_config = SettingsConfigDict(env_prefix="FLEETPINN_", extra="ignore")

    database_url: str = "sqlite:///./fleetpinn.db"

    @field_validator("database_url")
    @classmethod
    def _known_backend(cls, value: str) -> str:
        if not value.startswith(("sqlite", "postgresql")):
            raise ValueError("database_url must be a sqlite:// or postgresql:// URL")
        return value
