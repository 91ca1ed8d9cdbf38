"""locations: the fleet's catalogue of control points; inspections and forecasts name theirs

Revision ID: a7d4c2e9f5b3
Revises: 3f6b8d2c1e57
Create Date: 2026-11-28

The default location (id 1, every physical value NULL: the model's own) is created here, and the
rows stored before point at it, so a database of today answers as it did.  The forecast cache's
key gains the location (its rows are kept: they are the default location's).
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "a7d4c2e9f5b3"
down_revision: str | None = "3f6b8d2c1e57"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    locations = op.create_table(
        "locations",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=64), nullable=False),
        sa.Column("description", sa.Text(), server_default="", nullable=False),
        sa.Column("stress_factor", sa.Float(), server_default="1", nullable=False),
        sa.Column("stress_factor_by_mission", sa.JSON(none_as_null=True), nullable=True),
        sa.Column("geometry_factor", sa.Float(), nullable=True),
        sa.Column("geometry_table", sa.JSON(none_as_null=True), nullable=True),
        sa.Column("initial_crack_m", sa.Float(), nullable=True),
        sa.Column("critical_crack_m", sa.Float(), nullable=True),
        sa.Column("material", sa.String(length=128), nullable=True),
        sa.Column("growth_law", sa.JSON(none_as_null=True), nullable=True),
        sa.Column("inspection_method", sa.String(length=128), nullable=True),
        sa.Column("sizing_relative_sd", sa.Float(), nullable=True),
        sa.Column("pod_a50_m", sa.Float(), nullable=True),
        sa.Column("pod_a90_m", sa.Float(), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
        sa.CheckConstraint("stress_factor > 0", name=op.f("ck_locations_stress_factor_positive")),
        sa.CheckConstraint(
            "critical_crack_m > initial_crack_m", name=op.f("ck_locations_critical_above_initial")
        ),
        sa.CheckConstraint("pod_a90_m > pod_a50_m", name=op.f("ck_locations_pod_a90_above_a50")),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_locations")),
        sa.UniqueConstraint("name", name=op.f("uq_locations_name")),
    )
    op.create_table(
        "aircraft_locations",
        sa.Column("aircraft_id", sa.Integer(), nullable=False),
        sa.Column("location_id", sa.Integer(), nullable=False),
        sa.ForeignKeyConstraint(
            ["aircraft_id"],
            ["aircraft.id"],
            name=op.f("fk_aircraft_locations_aircraft_id_aircraft"),
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["location_id"],
            ["locations.id"],
            name=op.f("fk_aircraft_locations_location_id_locations"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("aircraft_id", "location_id", name=op.f("pk_aircraft_locations")),
    )
    now = sa.func.current_timestamp()
    op.execute(
        locations.insert().values(
            id=1,
            name="default",
            description="The control point of the fleet's model (every aircraft has it).",
            stress_factor=1.0,
            created_at=now,
            updated_at=now,
        )
    )
    if op.get_bind().dialect.name == "postgresql":  # the id was given: the serial moves past it
        op.execute("SELECT setval(pg_get_serial_sequence('locations', 'id'), 1)")
    with op.batch_alter_table("inspections") as batch:
        batch.add_column(sa.Column("location_id", sa.Integer(), server_default="1", nullable=False))
        batch.create_foreign_key(
            op.f("fk_inspections_location_id_locations"), "locations", ["location_id"], ["id"]
        )
    op.drop_index("ix_forecasts_version_stamp", table_name="forecasts")
    with op.batch_alter_table("forecasts") as batch:
        batch.add_column(sa.Column("location_id", sa.Integer(), server_default="1", nullable=False))
        batch.create_foreign_key(
            op.f("fk_forecasts_location_id_locations"),
            "locations",
            ["location_id"],
            ["id"],
            ondelete="CASCADE",
        )
        batch.drop_constraint("pk_forecasts", type_="primary")
        batch.create_primary_key("pk_forecasts", ["aircraft_id", "location_id", "model_version"])
    op.create_index(
        "ix_forecasts_version_stamp",
        "forecasts",
        ["model_version", "aircraft_id", "location_id", "stamp"],
    )
    # each location's own versions, one active per location; added in place (a batch copy of
    # model_versions would drop the old table, and with it every cached forecast by cascade)
    op.add_column(
        "model_versions",
        sa.Column("location_id", sa.Integer(), server_default="1", nullable=False),
    )
    op.drop_index("uq_model_versions_one_active", table_name="model_versions")
    op.create_index(
        "uq_model_versions_one_active",
        "model_versions",
        ["location_id", "status"],
        unique=True,
        sqlite_where=sa.text("status = 'active'"),
        postgresql_where=sa.text("status = 'active'"),
    )


def downgrade() -> None:
    # other locations' rows cannot go back to a key without the location
    op.execute("DELETE FROM forecasts WHERE location_id <> 1")
    op.execute("DELETE FROM inspections WHERE location_id <> 1")
    op.execute("DELETE FROM model_versions WHERE location_id <> 1")
    op.drop_index("uq_model_versions_one_active", table_name="model_versions")
    op.create_index(
        "uq_model_versions_one_active",
        "model_versions",
        ["status"],
        unique=True,
        sqlite_where=sa.text("status = 'active'"),
        postgresql_where=sa.text("status = 'active'"),
    )
    op.drop_column("model_versions", "location_id")
    op.drop_index("ix_forecasts_version_stamp", table_name="forecasts")
    with op.batch_alter_table("forecasts") as batch:
        batch.drop_constraint("pk_forecasts", type_="primary")
        batch.create_primary_key("pk_forecasts", ["aircraft_id", "model_version"])
        batch.drop_constraint(op.f("fk_forecasts_location_id_locations"), type_="foreignkey")
        batch.drop_column("location_id")
    op.create_index(
        "ix_forecasts_version_stamp", "forecasts", ["model_version", "aircraft_id", "stamp"]
    )
    with op.batch_alter_table("inspections") as batch:
        batch.drop_constraint(op.f("fk_inspections_location_id_locations"), type_="foreignkey")
        batch.drop_column("location_id")
    op.drop_table("aircraft_locations")
    op.drop_table("locations")
