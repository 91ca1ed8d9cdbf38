"""Index flights by (aircraft_id, flown_at): a tail's last flight and recent window.

Revision ID: b167e5c43617
Revises: 3e5ba8baea86
Create Date: 2026-11-21 14:51:13.648909
"""

from collections.abc import Sequence

from alembic import op

revision: str = "b167e5c43617"
down_revision: str | None = "3e5ba8baea86"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("flights", schema=None) as batch_op:
        batch_op.create_index(
            "ix_flights_aircraft_id_flown_at", ["aircraft_id", "flown_at"], unique=False
        )


def downgrade() -> None:
    with op.batch_alter_table("flights", schema=None) as batch_op:
        batch_op.drop_index("ix_flights_aircraft_id_flown_at")
