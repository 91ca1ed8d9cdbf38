from pathlib import Path

import numpy as np
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from sqlalchemy import func, inspect, select, text
from sqlalchemy.orm import Session

from app import migrate
from app.db import Base, make_engine
from app.services.records import spectra
from app.tables import SpectrumBlock

BEFORE_BLOCKS = "e2a7c4b91d05"  # flight_spectra: one row per flight

TABLES = {
    "aircraft",
    "flights",
    "inspections",
    "model_versions",
    "jobs",
    "forecasts",
    "api_keys",
    "audit_events",
    "spectrum_blocks",
    "flight_blocks",
    "locations",
    "aircraft_locations",
}


def _tables(url: str) -> set[str]:
    engine = make_engine(url)
    try:
        return set(inspect(engine).get_table_names()) - {"alembic_version"}
    finally:
        engine.dispose()


def test_upgrade_from_empty_matches_the_models_and_round_trips(database_url: str) -> None:
    """On each backend (its database starts as a copy of a migrated template: the SQLite file
    is removed first, so that one upgrades from empty)."""
    url = database_url
    if url.startswith("sqlite"):
        Path(url.removeprefix("sqlite:///")).unlink()
    migrate.upgrade(url)
    assert _tables(url) == TABLES
    engine = make_engine(url)
    with engine.connect() as connection:
        # The migrations build exactly the schema the ORM declares.
        assert compare_metadata(MigrationContext.configure(connection), Base.metadata) == []
    engine.dispose()
    migrate.downgrade(url, "base")
    assert _tables(url) == set()
    migrate.upgrade(url)
    assert _tables(url) == TABLES


def test_flight_spectra_rows_become_blocks_holding_the_same_bytes(tmp_path: Path) -> None:
    """A database of the one-row-per-flight layout (a real SQLite file): after the upgrade
    every flight reads back the very bytes it stored (cycles and history), the flights of
    each tail in one block; the downgrade writes the rows back as they were."""
    url = f"sqlite:///{tmp_path / 'old.db'}"
    migrate.upgrade(url, BEFORE_BLOCKS)
    rng = np.random.default_rng(7)
    # (flight pk, tail's id, flight_id, recorded, cycles, history), the tails' flights interleaved
    stored: list[tuple[int, int, str, str | None, bytes | None, bytes | None]] = []
    for pk, (aircraft, flight_id, recorded) in enumerate(
        [
            (1, "F1", None),
            (2, "F1", "cycles"),
            (1, "F2", "cycles"),
            (1, "F3", "stress_history"),
            (2, "F2", None),
            (1, "F4", "cycles"),
        ],
        start=1,
    ):
        cycles = history = None
        if recorded is not None:
            cycles = rng.normal(100.0, 30.0, (int(rng.integers(1, 12)), 3)).astype("<f8").tobytes()
        if recorded == "stress_history":
            history = rng.normal(0.0, 80.0, 40).astype("<f8").tobytes()
        stored.append((pk, aircraft, flight_id, recorded, cycles, history))
    engine = make_engine(url)
    try:
        with engine.begin() as connection:
            connection.execute(
                text(
                    "INSERT INTO aircraft (id, tail, created_at) VALUES"
                    " (1, 'A1', '2025-01-01 00:00:00'), (2, 'B2', '2025-01-01 00:00:00')"
                )
            )
            for pk, aircraft, flight_id, recorded, cycles, history in stored:
                connection.execute(
                    text(
                        "INSERT INTO flights (id, aircraft_id, flight_id, flown_at,"
                        " stress_range_mpa) VALUES (:pk, :aircraft, :flight_id,"
                        " '2025-01-01 00:00:00', 100.0)"
                    ),
                    {"pk": pk, "aircraft": aircraft, "flight_id": flight_id},
                )
                if recorded is not None:
                    connection.execute(
                        text("INSERT INTO flight_spectra VALUES (:pk, :recorded, :c, :h)"),
                        {"pk": pk, "recorded": recorded, "c": cycles, "h": history},
                    )
            old = connection.execute(text("SELECT * FROM flight_spectra ORDER BY flight_pk")).all()
        engine.dispose()
        migrate.upgrade(url)
        with Session(engine) as session:
            assert session.scalar(select(func.count()).select_from(SpectrumBlock)) == 2
            for _, aircraft, flight_id, recorded, cycles, history in stored:
                sent = spectra.stored(session, aircraft, flight_id)
                if recorded is None:
                    assert sent is None
                    continue
                assert sent is not None and sent.recorded == recorded
                assert sent.cycles.packed() == cycles
                read = sent.stress_history_mpa
                assert (None if read is None else read.astype("<f8").tobytes()) == history
            summary = spectra.summary(session, 1)
            assert summary is not None and summary.flights == 3
        engine.dispose()
        migrate.downgrade(url, BEFORE_BLOCKS)
        with engine.connect() as connection:
            back = connection.execute(text("SELECT * FROM flight_spectra ORDER BY flight_pk")).all()
        assert back == old
        assert "flight_blocks" not in _tables(url)
    finally:
        engine.dispose()
