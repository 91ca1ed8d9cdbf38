"""flight_spectra: a flight's recorded cycles (and stress history), beside its one range

Revision ID: e2a7c4b91d05
Revises: a7d4c2e9f5b3
Create Date: 2026-11-29

One row per flight recorded as cycles or as a stress history (app.tables.FlightSpectrum);
flights recorded as one range have none.  Deleting a flight (or its aircraft, whose trigger
deletes its flights) deletes its row.
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "e2a7c4b91d05"
down_revision: str | None = "a7d4c2e9f5b3"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "flight_spectra",
        sa.Column(
            "flight_pk", sa.BigInteger().with_variant(sa.Integer(), "sqlite"), nullable=False
        ),
        sa.Column("recorded", sa.String(length=16), nullable=False),
        sa.Column("cycles", sa.LargeBinary(), nullable=False),
        sa.Column("stress_history_mpa", sa.LargeBinary(), nullable=True),
        sa.ForeignKeyConstraint(
            ["flight_pk"],
            ["flights.id"],
            name=op.f("fk_flight_spectra_flight_pk_flights"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("flight_pk", name=op.f("pk_flight_spectra")),
    )


def downgrade() -> None:
    op.drop_table("flight_spectra")
