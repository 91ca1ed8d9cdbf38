"""Initial schema: aircraft, flights, inspections, model versions, jobs, forecasts.

Revision ID: 3e5ba8baea86
Revises:
Create Date: 2026-11-21 14:29:06.723019
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "3e5ba8baea86"
down_revision: str | None = None
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "aircraft",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("tail", sa.String(length=64), nullable=False),
        sa.Column("initial_crack_m", sa.Float(), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_aircraft")),
        sa.UniqueConstraint("tail", name=op.f("uq_aircraft_tail")),
    )
    op.create_table(
        "jobs",
        sa.Column("id", sa.String(length=36), nullable=False),
        sa.Column("kind", sa.String(length=32), nullable=False),
        sa.Column("status", sa.String(length=16), nullable=False),
        sa.Column("progress", sa.Float(), nullable=False),
        sa.Column("params", sa.JSON(), nullable=False),
        sa.Column("result", sa.JSON(), nullable=True),
        sa.Column("error", sa.Text(), nullable=True),
        sa.Column("cancel_requested", sa.Boolean(), nullable=False),
        sa.Column("worker", sa.String(length=128), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("started_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("finished_at", sa.DateTime(timezone=True), nullable=True),
        sa.CheckConstraint(
            "status IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')",
            name=op.f("ck_jobs_status_known"),
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_jobs")),
    )
    with op.batch_alter_table("jobs", schema=None) as batch_op:
        batch_op.create_index("ix_jobs_status_created_at", ["status", "created_at"], unique=False)

    op.create_table(
        "model_versions",
        sa.Column("version", sa.Integer(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("activated_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("status", sa.String(length=16), nullable=False),
        sa.Column("spec", sa.JSON(), nullable=False),
        sa.Column("training", sa.JSON(), nullable=False),
        sa.Column("metrics", sa.JSON(), nullable=False),
        sa.Column("weights", sa.LargeBinary(), nullable=False),
        sa.Column("job_id", sa.String(length=36), nullable=True),
        sa.CheckConstraint(
            "status IN ('candidate', 'active', 'retired')",
            name=op.f("ck_model_versions_status_known"),
        ),
        sa.PrimaryKeyConstraint("version", name=op.f("pk_model_versions")),
    )
    with op.batch_alter_table("model_versions", schema=None) as batch_op:
        batch_op.create_index("ix_model_versions_status", ["status"], unique=False)
        # At most one active version: activation retires the previous one in the same transaction.
        batch_op.create_index(
            "uq_model_versions_one_active",
            ["status"],
            unique=True,
            sqlite_where=sa.text("status = 'active'"),
            postgresql_where=sa.text("status = 'active'"),
        )

    op.create_table(
        "flights",
        sa.Column("id", sa.BigInteger().with_variant(sa.Integer(), "sqlite"), nullable=False),
        sa.Column("aircraft_id", sa.Integer(), nullable=False),
        sa.Column("flight_id", sa.String(length=128), nullable=False),
        sa.Column("flown_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("stress_range_mpa", sa.Float(), nullable=False),
        sa.Column("mission", sa.String(length=64), nullable=True),
        sa.CheckConstraint("stress_range_mpa > 0", name=op.f("ck_flights_stress_range_positive")),
        sa.ForeignKeyConstraint(
            ["aircraft_id"],
            ["aircraft.id"],
            name=op.f("fk_flights_aircraft_id_aircraft"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_flights")),
        sa.UniqueConstraint(
            "aircraft_id", "flight_id", name=op.f("uq_flights_aircraft_id_flight_id")
        ),
    )
    op.create_table(
        "forecasts",
        sa.Column("aircraft_id", sa.Integer(), nullable=False),
        sa.Column("model_version", sa.Integer(), nullable=False),
        sa.Column("computed_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("flights_flown", sa.Integer(), nullable=False),
        sa.Column("first_flown_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("origin", sa.DateTime(timezone=True), nullable=False),
        sa.Column("crack_length_m", sa.Float(), nullable=False),
        sa.Column("flights_per_day", sa.Float(), nullable=False),
        sa.Column("flights_to_critical", sa.Integer(), nullable=True),
        sa.Column("critical_date", sa.DateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(
            ["aircraft_id"],
            ["aircraft.id"],
            name=op.f("fk_forecasts_aircraft_id_aircraft"),
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["model_version"],
            ["model_versions.version"],
            name=op.f("fk_forecasts_model_version_model_versions"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("aircraft_id", "model_version", name=op.f("pk_forecasts")),
    )
    op.create_table(
        "inspections",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("aircraft_id", sa.Integer(), nullable=False),
        sa.Column("inspection_id", sa.String(length=128), nullable=False),
        sa.Column("inspected_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("crack_length_m", sa.Float(), nullable=False),
        sa.CheckConstraint("crack_length_m > 0", name=op.f("ck_inspections_crack_length_positive")),
        sa.ForeignKeyConstraint(
            ["aircraft_id"],
            ["aircraft.id"],
            name=op.f("fk_inspections_aircraft_id_aircraft"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_inspections")),
        sa.UniqueConstraint(
            "aircraft_id", "inspection_id", name=op.f("uq_inspections_aircraft_id_inspection_id")
        ),
    )


def downgrade() -> None:
    op.drop_table("inspections")
    op.drop_table("forecasts")
    op.drop_table("flights")
    with op.batch_alter_table("model_versions", schema=None) as batch_op:
        batch_op.drop_index("uq_model_versions_one_active")
        batch_op.drop_index("ix_model_versions_status")

    op.drop_table("model_versions")
    with op.batch_alter_table("jobs", schema=None) as batch_op:
        batch_op.drop_index("ix_jobs_status_created_at")

    op.drop_table("jobs")
    op.drop_table("aircraft")
