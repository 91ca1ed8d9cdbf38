"""Jobs: heartbeat_at and attempts, so a job whose worker died is claimed again.

Revision ID: 0be5e0f447dd
Revises: 3e5ba8baea86
Create Date: 2026-11-21 15:03:59.038764
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0be5e0f447dd"
down_revision: str | None = "3e5ba8baea86"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("jobs", schema=None) as batch_op:
        batch_op.add_column(sa.Column("attempts", sa.Integer(), server_default="0", nullable=False))
        batch_op.add_column(sa.Column("heartbeat_at", sa.DateTime(timezone=True), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("jobs", schema=None) as batch_op:
        batch_op.drop_column("heartbeat_at")
        batch_op.drop_column("attempts")
