"""forecasts: each tail's growth posterior (individual aircraft tracking)

Revision ID: 5d1c0a7e9b21
Revises: b4b747f7e490
Create Date: 2026-11-23
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "5d1c0a7e9b21"
down_revision: str | None = "b4b747f7e490"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("forecasts") as batch:
        batch.add_column(sa.Column("growth_samples", sa.LargeBinary(), nullable=True))
        batch.add_column(sa.Column("growth", sa.JSON(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("forecasts") as batch:
        batch.drop_column("growth")
        batch.drop_column("growth_samples")
