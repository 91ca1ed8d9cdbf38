"""forecasts: a stamp that changes on every write of a row (app.tables.Forecast.stamp), indexed

Revision ID: 3f6b8d2c1e57
Revises: 9c4d2e7f1a30
Create Date: 2026-11-27

Rows stored before it keep NULL, which nothing derived is kept for; their next write stamps them.
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "3f6b8d2c1e57"
down_revision: str | None = "9c4d2e7f1a30"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("forecasts") as batch:
        batch.add_column(sa.Column("stamp", sa.BigInteger(), nullable=True))
    op.create_index(
        "ix_forecasts_version_stamp", "forecasts", ["model_version", "aircraft_id", "stamp"]
    )


def downgrade() -> None:
    op.drop_index("ix_forecasts_version_stamp", table_name="forecasts")
    with op.batch_alter_table("forecasts") as batch:
        batch.drop_column("stamp")
