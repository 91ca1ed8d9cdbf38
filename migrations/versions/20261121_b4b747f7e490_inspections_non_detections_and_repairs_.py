"""Inspections: non-detections (threshold or PoD curve) and repairs; forecast uncertainty cache.

Revision ID: b4b747f7e490
Revises: 0be5e0f447dd
Create Date: 2026-11-21 15:16:47.798143
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "b4b747f7e490"
down_revision: str | None = "0be5e0f447dd"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("forecasts", schema=None) as batch_op:
        batch_op.add_column(sa.Column("crack_samples_m", sa.LargeBinary(), nullable=True))
        batch_op.add_column(sa.Column("recent_stress_mpa", sa.LargeBinary(), nullable=True))
        batch_op.add_column(sa.Column("risk", sa.JSON(), nullable=True))
        batch_op.add_column(sa.Column("bands", sa.JSON(), nullable=True))

    with op.batch_alter_table("inspections", schema=None) as batch_op:
        batch_op.add_column(
            sa.Column("detected", sa.Boolean(), server_default=sa.true(), nullable=False)
        )
        batch_op.add_column(sa.Column("detection_threshold_m", sa.Float(), nullable=True))
        batch_op.add_column(sa.Column("pod_a50_m", sa.Float(), nullable=True))
        batch_op.add_column(sa.Column("pod_a90_m", sa.Float(), nullable=True))
        batch_op.add_column(
            sa.Column("repaired", sa.Boolean(), server_default=sa.false(), nullable=False)
        )
        batch_op.add_column(sa.Column("crack_after_repair_m", sa.Float(), nullable=True))
        batch_op.alter_column("crack_length_m", existing_type=sa.Float(), nullable=True)
        batch_op.create_check_constraint("crack_after_repair_positive", "crack_after_repair_m > 0")
        batch_op.create_check_constraint(
            "no_crack_when_not_detected", "detected OR crack_length_m IS NULL"
        )


def downgrade() -> None:
    # The old schema has no place for a non-detection: those rows are dropped.
    op.execute("DELETE FROM inspections WHERE crack_length_m IS NULL")
    with op.batch_alter_table("inspections", schema=None) as batch_op:
        batch_op.drop_constraint("no_crack_when_not_detected", type_="check")
        batch_op.drop_constraint("crack_after_repair_positive", type_="check")
        batch_op.alter_column("crack_length_m", existing_type=sa.Float(), nullable=False)
        batch_op.drop_column("crack_after_repair_m")
        batch_op.drop_column("repaired")
        batch_op.drop_column("pod_a90_m")
        batch_op.drop_column("pod_a50_m")
        batch_op.drop_column("detection_threshold_m")
        batch_op.drop_column("detected")

    with op.batch_alter_table("forecasts", schema=None) as batch_op:
        batch_op.drop_column("bands")
        batch_op.drop_column("risk")
        batch_op.drop_column("recent_stress_mpa")
        batch_op.drop_column("crack_samples_m")
