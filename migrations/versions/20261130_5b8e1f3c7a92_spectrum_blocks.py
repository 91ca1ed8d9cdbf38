"""spectrum_blocks: one upload's recorded cycles of a tail in one row; flight_blocks: where

Revision ID: 5b8e1f3c7a92
Revises: e2a7c4b91d05
Create Date: 2026-11-30

Why: flight_spectra held one row per flight; a cycle file of 300 tails x 7,300 flights wrote
2.19 M rows of a 192-byte blob, ~7.5 s of SQLite's B-tree work in an upload whose single-range
form takes ~10 s (benchmarks/RESULTS.md, issue 21).  A block (app.tables.SpectrumBlock) holds
the cycles of one tail's flights of one upload back to back with their offsets, and a narrow
flight_blocks row per flight names its block and its place in it (deleted with its flight:
cascade).  Readers go from the flights through flight_blocks to the blocks, so a deleted
flight's cycles are never read, whatever is left in its block.  The flights table is unchanged
(two nullable columns on it made the single-range upload's insert ~1.6x slower).

Upgrade: every aircraft's flight_spectra rows become one block (its flights in id order), the
bytes unchanged; downgrade writes them back one row per flight.
"""

import struct
from collections.abc import Sequence
from itertools import accumulate

import sqlalchemy as sa
from alembic import op

revision: str = "5b8e1f3c7a92"
down_revision: str | None = "e2a7c4b91d05"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_ROW = 3 * 8  # a cycle: stress_range_mpa, load_ratio, count as little-endian float64


def _starts(blobs: Sequence[bytes | None], unit: int) -> bytes:
    """(flights + 1,) little-endian int64 offsets; struct, not numpy: `fleetpinn keys` and
    `client` load the migrations and must start without the model stack."""
    sizes = [0 if b is None else len(b) // unit for b in blobs]
    starts = [0, *accumulate(sizes)]
    return struct.pack(f"<{len(starts)}q", *starts)


def _offsets(blob: bytes) -> tuple[int, ...]:
    return struct.unpack(f"<{len(blob) // 8}q", blob)


def upgrade() -> None:
    op.create_table(
        "spectrum_blocks",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("aircraft_id", sa.Integer(), nullable=False),
        sa.Column("cycle_starts", sa.LargeBinary(), nullable=False),
        sa.Column("history_starts", sa.LargeBinary(), nullable=True),
        sa.Column("cycles", sa.LargeBinary(), nullable=False),
        sa.Column("stress_history_mpa", sa.LargeBinary(), nullable=True),
        sa.ForeignKeyConstraint(
            ["aircraft_id"],
            ["aircraft.id"],
            name=op.f("fk_spectrum_blocks_aircraft_id_aircraft"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_spectrum_blocks")),
    )
    op.create_table(
        "flight_blocks",
        sa.Column(
            "flight_pk", sa.BigInteger().with_variant(sa.Integer(), "sqlite"), nullable=False
        ),
        sa.Column("spectrum_block_id", sa.Integer(), nullable=False),
        sa.Column("spectrum_index", sa.Integer(), nullable=False),
        sa.ForeignKeyConstraint(
            ["flight_pk"],
            ["flights.id"],
            name=op.f("fk_flight_blocks_flight_pk_flights"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("flight_pk", name=op.f("pk_flight_blocks")),
    )
    connection = op.get_bind()
    aircraft_ids = connection.execute(
        sa.text(
            "SELECT DISTINCT f.aircraft_id FROM flight_spectra s"
            " JOIN flights f ON f.id = s.flight_pk ORDER BY f.aircraft_id"
        )
    ).scalars()
    blocks = sa.table(
        "spectrum_blocks",
        sa.column("id", sa.Integer()),
        sa.column("aircraft_id", sa.Integer()),
        sa.column("cycle_starts", sa.LargeBinary()),
        sa.column("history_starts", sa.LargeBinary()),
        sa.column("cycles", sa.LargeBinary()),
        sa.column("stress_history_mpa", sa.LargeBinary()),
    )
    for aircraft_id in list(aircraft_ids):
        rows = connection.execute(
            sa.text(
                "SELECT f.id, s.cycles, s.stress_history_mpa FROM flight_spectra s"
                " JOIN flights f ON f.id = s.flight_pk WHERE f.aircraft_id = :aircraft"
                " ORDER BY f.id"
            ),
            {"aircraft": aircraft_id},
        ).all()
        cycles = [bytes(r[1]) for r in rows]
        histories = [None if r[2] is None else bytes(r[2]) for r in rows]
        any_history = any(h is not None for h in histories)
        block_id = connection.execute(
            blocks.insert()
            .values(
                aircraft_id=aircraft_id,
                cycle_starts=_starts(cycles, _ROW),
                history_starts=_starts(histories, 8) if any_history else None,
                cycles=b"".join(cycles),
                stress_history_mpa=b"".join(h or b"" for h in histories) if any_history else None,
            )
            .returning(blocks.c.id)
        ).scalar_one()
        connection.execute(
            sa.text(
                "INSERT INTO flight_blocks (flight_pk, spectrum_block_id, spectrum_index)"
                " VALUES (:id, :block, :at)"
            ),
            [{"block": block_id, "at": at, "id": r[0]} for at, r in enumerate(rows)],
        )
    op.drop_table("flight_spectra")


def downgrade() -> None:
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
    connection = op.get_bind()
    block_ids = connection.execute(sa.text("SELECT id FROM spectrum_blocks ORDER BY id")).scalars()
    for block_id in list(block_ids):
        block = connection.execute(
            sa.text(
                "SELECT aircraft_id, cycle_starts, history_starts, cycles, stress_history_mpa"
                " FROM spectrum_blocks WHERE id = :block"
            ),
            {"block": block_id},
        ).one()
        flights = connection.execute(
            sa.text(
                "SELECT flight_pk, spectrum_index FROM flight_blocks"
                " WHERE spectrum_block_id = :block"
            ),
            {"block": block_id},
        ).all()
        if not flights:
            continue
        cycle_starts = _offsets(block.cycle_starts)
        history_starts = None if block.history_starts is None else _offsets(block.history_starts)
        rows = []
        for flight_pk, at in flights:
            history = None
            if history_starts is not None and history_starts[at + 1] > history_starts[at]:
                first, last = 8 * history_starts[at], 8 * history_starts[at + 1]
                history = bytes(block.stress_history_mpa[first:last])
            rows.append(
                {
                    "flight_pk": flight_pk,
                    "recorded": "cycles" if history is None else "stress_history",
                    "cycles": bytes(
                        block.cycles[_ROW * cycle_starts[at] : _ROW * cycle_starts[at + 1]]
                    ),
                    "stress_history_mpa": history,
                }
            )
        connection.execute(
            sa.text(
                "INSERT INTO flight_spectra (flight_pk, recorded, cycles, stress_history_mpa)"
                " VALUES (:flight_pk, :recorded, :cycles, :stress_history_mpa)"
            ).bindparams(
                sa.bindparam("cycles", type_=sa.LargeBinary()),
                sa.bindparam("stress_history_mpa", type_=sa.LargeBinary()),
            ),
            rows,
        )
    op.drop_table("flight_blocks")
    op.drop_table("spectrum_blocks")
