"""API keys, the audit log (who wrote what), inspection assessments against the forecast.

Flights, inspections and jobs point at the audit event that stored them; rows stored before
this revision keep a null audit_id.  On SQLite the foreign keys rebuild the three tables once
(batch mode copies them).

Revision ID: 7a3e91c2d4f0
Revises: 7c3e2a9d4f10
Create Date: 2026-11-25
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "7a3e91c2d4f0"
down_revision: str | None = "7c3e2a9d4f10"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_AUDITED = ("flights", "inspections", "jobs")


def upgrade() -> None:
    op.create_table(
        "api_keys",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("key_id", sa.String(length=16), nullable=False),
        sa.Column("name", sa.String(length=64), nullable=False),
        sa.Column("role", sa.String(length=8), nullable=False),
        sa.Column("salt", sa.String(length=32), nullable=False),
        sa.Column("key_hash", sa.String(length=64), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("revoked_at", sa.DateTime(timezone=True), nullable=True),
        sa.CheckConstraint(
            "role IN ('read', 'write', 'admin')", name=op.f("ck_api_keys_role_known")
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_api_keys")),
        sa.UniqueConstraint("key_id", name=op.f("uq_api_keys_key_id")),
    )
    op.create_index(
        "uq_api_keys_live_name",
        "api_keys",
        ["name"],
        unique=True,
        sqlite_where=sa.text("revoked_at IS NULL"),
        postgresql_where=sa.text("revoked_at IS NULL"),
    )
    op.create_table(
        "audit_events",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("api_key_id", sa.Integer(), nullable=True),
        sa.Column("actor", sa.String(length=80), nullable=False),
        sa.Column("role", sa.String(length=8), nullable=False),
        sa.Column("action", sa.String(length=32), nullable=False),
        sa.Column("subject", sa.String(length=300), nullable=False),
        sa.Column("request_id", sa.String(length=128), nullable=True),
        sa.Column("detail", sa.JSON(), nullable=False),
        sa.ForeignKeyConstraint(
            ["api_key_id"], ["api_keys.id"], name=op.f("fk_audit_events_api_key_id_api_keys")
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_audit_events")),
    )
    op.create_index("ix_audit_events_subject", "audit_events", ["subject"], unique=False)

    for table in _AUDITED:
        with op.batch_alter_table(table) as batch:
            batch.add_column(sa.Column("audit_id", sa.Integer(), nullable=True))
            if table == "inspections":
                batch.add_column(sa.Column("forecast_crack_m", sa.Float(), nullable=True))
                batch.add_column(sa.Column("forecast_z", sa.Float(), nullable=True))
                batch.add_column(
                    sa.Column("flagged", sa.Boolean(), server_default=sa.false(), nullable=False)
                )
            batch.create_foreign_key(
                f"fk_{table}_audit_id_audit_events", "audit_events", ["audit_id"], ["id"]
            )


def downgrade() -> None:
    for table in reversed(_AUDITED):
        with op.batch_alter_table(table) as batch:
            batch.drop_constraint(f"fk_{table}_audit_id_audit_events", type_="foreignkey")
            if table == "inspections":
                batch.drop_column("flagged")
                batch.drop_column("forecast_z")
                batch.drop_column("forecast_crack_m")
            batch.drop_column("audit_id")
    op.drop_index("ix_audit_events_subject", table_name="audit_events")
    op.drop_table("audit_events")
    op.drop_index("uq_api_keys_live_name", table_name="api_keys")
    op.drop_table("api_keys")
