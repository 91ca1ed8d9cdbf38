"""Bulk flight upload through the service against a bare pandas + sqlite3 load, in one run.

    .venv/bin/python -m benchmarks.ingest                       # thesis fleet: 300 x 7,300 flights
    .venv/bin/python -m benchmarks.ingest --backend postgresql  # the same on PostgreSQL
    .venv/bin/python -m benchmarks.ingest --aircraft-per-mix 10 --years 1   # a quick look

Both paths start from the same CSV file of the synthetic fleet (model.fleet):
  reference: SQLite: pandas.read_csv, then sqlite3 executemany of every row into one table with a
             unique index (tail, flight_id) and one commit; PostgreSQL: a bare COPY of the CSV
             file (FORMAT csv) into such a table (the server parses it), and a bare COPY of the
             same rows into the service's own flights table; no validation, no duplicate check.
  service:   POST /flights/upload (multipart) to a real `uvicorn app.main:app` on a fresh SQLite
             file or PostgreSQL database (`make postgres`): upload, validation
             (model.record_validation), tail creation, duplicate detection, insert (PostgreSQL:
             binary COPY).
Then the same file is uploaded again (all duplicates), the demo's 15 inspections are posted, the
default model is retrained, and single-aircraft forecasts are timed (cache cold, then warm).
Checks: every tail's served crack against `fleetpinn predict` with the served model file on the
same CSV, and the ranking's top 20 against the 20 largest cracks (served and true).  Prints one
JSON object; `ratio` = service seconds / reference seconds (goals: <= 3 on SQLite, <= 2 against
the bare COPY on PostgreSQL).
"""

from __future__ import annotations

import argparse
import json
import sqlite3
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pandas as pd

from app.commands import create_key
from app.config import Settings
from app.local_server import uvicorn_server, wait_for_job
from model.fleet import FleetConfig, generate_fleet, scheduled_inspection


def reference_load(csv: Path, database: Path) -> float:
    """Seconds for read_csv + executemany into an indexed table + commit."""
    started = time.perf_counter()
    frame = pd.read_csv(csv, dtype={"tail": str, "flight_id": str, "mission": str})
    connection = sqlite3.connect(database)
    connection.execute(
        "CREATE TABLE flights (tail TEXT NOT NULL, flight_id TEXT NOT NULL, flown_at TEXT NOT NULL,"
        " stress_range_mpa REAL NOT NULL, mission TEXT)"
    )
    connection.execute("CREATE UNIQUE INDEX uq_flights ON flights (tail, flight_id)")
    connection.executemany(
        "INSERT INTO flights VALUES (?, ?, ?, ?, ?)",
        zip(
            frame["tail"].tolist(),
            frame["flight_id"].tolist(),
            frame["flown_at"].tolist(),
            frame["stress_range_mpa"].tolist(),
            frame["mission"].tolist(),
            strict=True,
        ),
    )
    connection.commit()
    connection.close()
    return time.perf_counter() - started


def _psycopg(database_url: str) -> Any:
    import psycopg
    from sqlalchemy.engine import make_url

    url = make_url(database_url)
    return psycopg.connect(
        host=url.host, port=url.port, user=url.username, password=url.password, dbname=url.database
    )


def reference_copy(csv: Path, database_url: str) -> float:
    """Seconds for a bare COPY of the CSV file into an indexed table + commit (PostgreSQL)."""
    started = time.perf_counter()
    with _psycopg(database_url) as connection:
        connection.execute(
            "CREATE TABLE flights_reference (tail text NOT NULL, flight_id text NOT NULL,"
            " flown_at timestamptz NOT NULL, stress_range_mpa float8 NOT NULL, mission text)"
        )
        connection.execute("CREATE UNIQUE INDEX ON flights_reference (tail, flight_id)")
        copy_sql = "COPY flights_reference FROM STDIN (FORMAT csv, HEADER)"
        with connection.cursor().copy(copy_sql) as copy, csv.open("rb") as handle:
            while block := handle.read(1 << 20):
                copy.write(block)
    return time.perf_counter() - started


def reference_copy_same_table(csv: Path, database_url: str, work: Path) -> float:
    """Seconds for a bare COPY of the same rows into the service's own `flights` table (its
    reference check, check constraint, unique index and key) of a migrated database whose
    aircraft and one audit event exist; the file is first rewritten with aircraft ids in place
    of tails and that event's id (not timed), as the service stores them."""
    from app import migrate

    migrate.upgrade(database_url)
    frame = pd.read_csv(csv, dtype={"tail": str, "flight_id": str, "mission": str})
    tails = pd.unique(frame["tail"])
    frame.insert(
        0, "aircraft_id", pd.Series(range(1, len(tails) + 1), index=tails)[frame["tail"]].to_numpy()
    )
    frame["audit_id"] = 1
    by_id = work / "flights_by_id.csv"
    frame.drop(columns="tail").to_csv(by_id, index=False)
    with _psycopg(database_url) as connection:
        connection.execute(
            "INSERT INTO aircraft (id, tail, created_at) SELECT i, t, now() "
            "FROM unnest(%s::int[], %s::text[]) AS u(i, t)",
            (list(range(1, len(tails) + 1)), list(tails)),
        )
        connection.execute(
            "INSERT INTO audit_events (id, at, actor, role, action, subject, detail) "
            "VALUES (1, now(), 'benchmark', 'admin', 'flights.ingest', 'fleet', '{}')"
        )
        connection.commit()
        columns = "aircraft_id, flight_id, flown_at, stress_range_mpa, mission, audit_id"
        started = time.perf_counter()
        with (
            connection.cursor().copy(
                f"COPY flights ({columns}) FROM STDIN (FORMAT csv, HEADER)"
            ) as copy,
            by_id.open("rb") as handle,
        ):
            while block := handle.read(1 << 20):
                copy.write(block)
        connection.commit()
    return time.perf_counter() - started


def _upload(client: httpx.Client, csv: Path) -> tuple[float, dict[str, Any]]:
    started = time.perf_counter()
    with csv.open("rb") as handle:
        answer = client.post("/flights/upload", files={"file": (csv.name, handle, "text/csv")})
    seconds = time.perf_counter() - started
    answer.raise_for_status()
    body: dict[str, Any] = answer.json()
    return seconds, body


def _predict(model: Path, flights: Path, out: Path) -> pd.Series:
    """Crack after each tail's last flight from the offline `fleetpinn predict` (tail-indexed)."""
    fleetpinn = Path(sys.executable).parent / "fleetpinn"
    command: list[str | Path] = [
        fleetpinn,
        "predict",
        "--model",
        model,
        "--flights",
        flights,
        "--out",
        out,
    ]
    subprocess.run(command, check=True, capture_output=True)
    return pd.read_csv(out).set_index("tail")["crack_length_m"]


def _forecast_latency(client: httpx.Client, tails: list[str], repeats: int) -> dict[str, float]:
    """Cold: the tail's cached state was just voided (a new initial crack), so the request marches
    its whole history and searches its time to critical; warm: served from the cached state."""
    cold, warm = [], []
    for tail in tails:
        client.put(f"/aircraft/{tail}", json={"initial_crack_m": 0.005}).raise_for_status()
        started = time.perf_counter()
        client.get(f"/aircraft/{tail}/forecast").raise_for_status()
        cold.append(time.perf_counter() - started)
        for _ in range(repeats):
            started = time.perf_counter()
            client.get(f"/aircraft/{tail}/forecast").raise_for_status()
            warm.append(time.perf_counter() - started)
    return {
        "forecast_cold_median_ms": 1000 * statistics.median(cold),
        "forecast_warm_median_ms": 1000 * statistics.median(warm),
        "forecast_warm_p95_ms": 1000 * sorted(warm)[int(0.95 * (len(warm) - 1))],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--aircraft-per-mix", type=int, default=100)
    parser.add_argument("--years", type=int, default=5)
    parser.add_argument("--forecast-tails", type=int, default=20)
    parser.add_argument("--backend", choices=("sqlite", "postgresql"), default="sqlite")
    args = parser.parse_args()
    databases: list[str] = []
    try:
        _run(args, databases)
    finally:
        if databases:
            from tests import postgres

            for name in databases:
                postgres.drop_database(name)


def _run(args: argparse.Namespace, databases: list[str]) -> None:

    with tempfile.TemporaryDirectory(prefix="fleetpinn-ingest-") as folder:
        work = Path(folder)
        fleet = generate_fleet(
            FleetConfig(aircraft_per_mix=args.aircraft_per_mix, years=args.years)
        )
        csv = work / "flights.csv"
        fleet.flights_frame().to_csv(csv, index=False)
        rows = fleet.size * fleet.stress_range_mpa.shape[1]
        csv_mb = csv.stat().st_size / 1e6

        same_table_s = None
        if args.backend == "postgresql":
            from tests import postgres

            if reason := postgres.unavailable():
                raise SystemExit(reason)
            databases += [postgres.create_database("fleetpinn_bench") for _ in range(3)]
            reference_s = reference_copy(csv, postgres.url_of(databases[0]))
            same_table_s = reference_copy_same_table(csv, postgres.url_of(databases[2]), work)
            service_url = postgres.url_of(databases[1])
        else:
            reference_s = reference_load(csv, work / "reference.db")
            service_url = f"sqlite:///{work / 'service.db'}"
        env = {
            "FLEETPINN_DATABASE_URL": service_url,
            "FLEETPINN_KERNEL": "physics",
            # the thesis fleet is one file of 2.19 M rows, past the default's million
            "FLEETPINN_MAX_UPLOAD_ROWS": str(max(rows, 1)),
            "OMP_NUM_THREADS": "1",
        }
        database = Settings(database_url=env["FLEETPINN_DATABASE_URL"])
        with uvicorn_server("app.main:app", env, log=work / "server.log") as base:
            key = create_key("admin", "benchmark", replace=True, settings=database).key
            headers = {"Authorization": f"Bearer {key}"}
            with httpx.Client(base_url=base, timeout=600, headers=headers) as client:
                upload_s, first = _upload(client, csv)
                resend_s, second = _upload(client, csv)
                assert first["inserted"] == rows and second["duplicates"] == rows, (first, second)
                # The demo's inspections (15 tails, uniform coverage) and the default model.
                inspections = work / "inspections.csv"
                fleet.inspections_frame(
                    scheduled_inspection(fleet, min(15, fleet.size), "uniform-coverage")
                ).to_csv(inspections, index=False)
                for row in pd.read_csv(inspections).to_dict("records"):
                    tail = row.pop("tail")
                    client.post(f"/aircraft/{tail}/inspections", json=row).raise_for_status()
                job = client.post("/models/retrain").json()
                retrain_started = time.perf_counter()
                wait_for_job(client, job["job_id"], timeout_s=3600)
                retrain_s = time.perf_counter() - retrain_started
                version = client.get("/ready").json()["model_version"]
                latency = _forecast_latency(client, fleet.tails[: args.forecast_tails], repeats=10)
                started = time.perf_counter()
                ranked = client.get("/fleet/ranking", params={"limit": 20}).json()["items"]
                ranking_ms = 1000 * (time.perf_counter() - started)
                served = {
                    t: client.get(f"/aircraft/{t}/forecast").json()["crack_length_m"]
                    for t in fleet.tails
                }
                (work / "model.pt").write_bytes(client.get(f"/models/{version}/file").content)
        offline = _predict(work / "model.pt", csv, work / "pred.csv")
    tails = pd.Index(fleet.tails)
    served_crack = pd.Series(served).reindex(tails).to_numpy()
    offline_crack = offline.reindex(tails).to_numpy()
    largest = set(tails[np.argsort(served_crack)[-20:]])
    true_largest = set(tails[np.argsort(fleet.final_crack_m)[-20:]])
    top20 = {item["tail"] for item in ranked}
    checks = {
        "http_vs_predict_max_rel_diff": float(np.max(np.abs(served_crack / offline_crack - 1))),
        "ranking_top20_in_largest20_served": len(top20 & largest),
        "ranking_top20_in_largest20_true": len(top20 & true_largest),
    }

    print(
        json.dumps(
            {
                "backend": args.backend,
                "aircraft": fleet.size,
                "rows": rows,
                "csv_mb": round(csv_mb, 1),
                "reference_s": round(reference_s, 2),
                "upload_s": round(upload_s, 2),
                "ratio": round(upload_s / reference_s, 2),
                **(
                    {}
                    if same_table_s is None
                    else {
                        "reference_same_table_s": round(same_table_s, 2),
                        "ratio_same_table": round(upload_s / same_table_s, 2),
                    }
                ),
                "resend_all_duplicates_s": round(resend_s, 2),
                "retrain_and_fill_forecasts_s": round(retrain_s, 2),
                "ranking_ms": round(ranking_ms, 1),
                **{k: round(v, 1) for k, v in latency.items()},
                **checks,
            }
        )
    )


if __name__ == "__main__":
    main()
