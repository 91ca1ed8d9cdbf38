"""Where a bulk COPY into PostgreSQL's `flights` spends its time: variants of the table, one run.

    .venv/bin/python -m benchmarks.pg_copy                      # 300 x 7,300 flights (2.19 M rows)
    .venv/bin/python -m benchmarks.pg_copy --aircraft-per-mix 10 --years 1   # a quick look

Every variant COPYs the same CSV (FORMAT csv, the server parses it) into a fresh database
migrated to head whose 300 aircraft and one audit event exist, and commits:
  reference          a plain table (tail, flight_id, ...) with one unique index, as
                     benchmarks.ingest's bare COPY
  flights            the service's table as migrated (whatever head declares)
  +fk                head's table plus per-row foreign keys to aircraft and audit_events (the
                     schema before revision 9c4d2e7f1a30)
  -trigger           head's table without its statement-level reference check
  staging            COPY into a temporary table, then one INSERT ... SELECT ... ON CONFLICT DO
                     NOTHING into `flights`
Each variant runs --repeats times, round robin, with a reference COPY before the first round and
after each.  Prints one JSON object: every run's seconds, each variant's median, and its ratio
to the mean reference.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pandas as pd

from benchmarks.ingest import _psycopg, reference_copy
from model.fleet import FleetConfig, generate_fleet

_COLUMNS = "aircraft_id, flight_id, flown_at, stress_range_mpa, mission, audit_id"

_PER_ROW_FKS = (
    "ALTER TABLE flights ADD CONSTRAINT fk_flights_aircraft_id_aircraft FOREIGN KEY (aircraft_id)"
    " REFERENCES aircraft (id) ON DELETE CASCADE",
    "ALTER TABLE flights ADD CONSTRAINT fk_flights_audit_id_audit_events FOREIGN KEY (audit_id)"
    " REFERENCES audit_events (id)",
)
_NO_TRIGGER = ("DROP TRIGGER flights_references_inserted ON flights",)


def _by_id(csv: Path, out: Path) -> int:
    """The fleet CSV with aircraft ids 1..n in place of tails and audit event 1; returns n."""
    frame = pd.read_csv(csv, dtype={"tail": str, "flight_id": str, "mission": str})
    tails = pd.unique(frame["tail"])
    ids = pd.Series(range(1, len(tails) + 1), index=tails)[frame["tail"]].to_numpy()
    frame.insert(0, "aircraft_id", ids)
    frame["audit_id"] = 1
    frame.drop(columns="tail").to_csv(out, index=False)
    return len(tails)


def _prepared(database_url: str, aircraft: int, ddl: tuple[str, ...]) -> Any:
    """A connection to a migrated database with its aircraft, one audit event and `ddl`."""
    from app import migrate

    migrate.upgrade(database_url)
    connection = _psycopg(database_url)
    connection.execute(
        "INSERT INTO aircraft (id, tail, created_at) SELECT i, 'T' || i, now() "
        "FROM generate_series(1, %s) AS i",
        (aircraft,),
    )
    connection.execute(
        "INSERT INTO audit_events (id, at, actor, role, action, subject, detail) "
        "VALUES (1, now(), 'bench', 'admin', 'flights.ingest', 'fleet', '{}')"
    )
    for statement in ddl:
        connection.execute(statement)
    connection.commit()
    return connection


def _copy(connection: Any, statement: str, csv: Path) -> None:
    with connection.cursor().copy(statement) as copy, csv.open("rb") as handle:
        while block := handle.read(1 << 20):
            copy.write(block)


def copy_into_flights(database_url: str, by_id: Path, aircraft: int, ddl: tuple[str, ...]) -> float:
    """Seconds for a COPY of every row into `flights` + commit."""
    with _prepared(database_url, aircraft, ddl) as connection:
        started = time.perf_counter()
        _copy(connection, f"COPY flights ({_COLUMNS}) FROM STDIN (FORMAT csv, HEADER)", by_id)
        connection.commit()
        seconds = time.perf_counter() - started
        rows = connection.execute("SELECT count(*) FROM flights").fetchone()[0]
    assert rows > 0, "nothing stored"
    return seconds


def copy_via_staging(database_url: str, by_id: Path, aircraft: int, ddl: tuple[str, ...]) -> float:
    """Seconds for a COPY into a temporary table, one INSERT ... SELECT ... ON CONFLICT DO
    NOTHING into `flights`, and the commit."""
    with _prepared(database_url, aircraft, ddl) as connection:
        started = time.perf_counter()
        connection.execute(
            "CREATE TEMPORARY TABLE staged (aircraft_id int, flight_id text, flown_at timestamptz,"
            " stress_range_mpa float8, mission text, audit_id int) ON COMMIT DROP"
        )
        _copy(connection, f"COPY staged ({_COLUMNS}) FROM STDIN (FORMAT csv, HEADER)", by_id)
        connection.execute(
            f"INSERT INTO flights ({_COLUMNS}) SELECT {_COLUMNS} FROM staged "
            "ON CONFLICT (aircraft_id, flight_id) DO NOTHING"
        )
        connection.commit()
        return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--aircraft-per-mix", type=int, default=100)
    parser.add_argument("--years", type=int, default=5)
    parser.add_argument("--repeats", type=int, default=2, help="runs of each variant")
    args = parser.parse_args()
    from tests import postgres

    if reason := postgres.unavailable():
        raise SystemExit(reason)
    databases: list[str] = []
    try:
        with tempfile.TemporaryDirectory(prefix="fleetpinn-pgcopy-") as folder:
            work = Path(folder)
            fleet = generate_fleet(
                FleetConfig(aircraft_per_mix=args.aircraft_per_mix, years=args.years)
            )
            csv = work / "flights.csv"
            fleet.flights_frame().to_csv(csv, index=False)
            aircraft = _by_id(csv, work / "by_id.csv")

            def fresh() -> str:
                databases.append(postgres.create_database("fleetpinn_pgcopy"))
                return postgres.url_of(databases[-1])

            variants: dict[str, Callable[[], float]] = {
                "flights": lambda: copy_into_flights(fresh(), work / "by_id.csv", aircraft, ()),
                "+fk": lambda: copy_into_flights(
                    fresh(), work / "by_id.csv", aircraft, _PER_ROW_FKS
                ),
                "-trigger": lambda: copy_into_flights(
                    fresh(), work / "by_id.csv", aircraft, _NO_TRIGGER
                ),
                "staging": lambda: copy_via_staging(fresh(), work / "by_id.csv", aircraft, ()),
            }
            # Round robin, the reference first and last: load that comes and goes on a shared
            # machine falls on every variant alike.
            references = [reference_copy(csv, fresh())]
            runs: dict[str, list[float]] = {name: [] for name in variants}
            for _ in range(args.repeats):
                for name, run in variants.items():
                    runs[name].append(run())
                references.append(reference_copy(csv, fresh()))
            seconds = {name: statistics.median(s) for name, s in runs.items()}
    finally:
        for name in databases:
            postgres.drop_database(name)
    reference = statistics.mean(references)
    print(
        json.dumps(
            {
                "rows": fleet.size * fleet.stress_range_mpa.shape[1],
                "reference_s": [round(s, 2) for s in references],
                **{f"{name}_runs_s": [round(s, 2) for s in r] for name, r in runs.items()},
                **{f"{name}_s": round(s, 2) for name, s in seconds.items()},
                **{f"{name}_ratio": round(s / reference, 2) for name, s in seconds.items()},
            }
        )
    )


if __name__ == "__main__":
    main()
