"""location crack cases: a location may give its crack case, limit stress and strengths, and
Walker's gamma below R = 0

Revision ID: c41a7e5d9b20
Revises: 5b8e1f3c7a92
Create Date: 2026-12-02

Why (issue 41): a structures engineer gives a crack case and its dimensions, not a geometry
table, and the stress the part must carry, not a critical crack; the service computes beta(a)
(model.crack_cases) and a_crit from the material's toughness.  Nullable columns: the
case as {"type": ..., dimensions}, the limit stress, and the location's own K_c (or K_IC) and
yield strength where its material's row has none; and Walker's gamma for cycles at R < 0
(null: the R >= 0 gamma, as before).  Existing rows keep null (their factor or table, typed
a_crit and one gamma), so they answer as before.
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "c41a7e5d9b20"
down_revision: str | None = "5b8e1f3c7a92"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


_FLOATS = (
    "limit_stress_mpa",
    "fracture_toughness_mpa_sqrt_m",
    "yield_strength_mpa",
    "gamma_below_zero",
)


# plain ADD / DROP COLUMN, not a batch copy: other tables reference locations, and SQLite's
# copy-and-rename would drop the referenced table (SQLite >= 3.35 drops a column in place)
def upgrade() -> None:
    op.add_column("locations", sa.Column("crack_case", sa.JSON(none_as_null=True), nullable=True))
    for name in _FLOATS:
        op.add_column("locations", sa.Column(name, sa.Float(), nullable=True))


def downgrade() -> None:
    for name in (*reversed(_FLOATS), "crack_case"):
        op.drop_column("locations", name)
