"""Uploading flights as cycles against one range per flight, measured in the same run.

    .venv/bin/python -m benchmarks.spectra_ingest --per-mix 20     # 60 tails x 7,300 flights

The spectra fleet (model/spectra_fleet.py: up to 10 cycles a flight) written twice: as the
flights file (one damage-equivalent range per flight) and as the cycle file (one row per cycle,
what `fleetpinn spectrum` writes); each uploaded by POST /flights/upload into a fresh, migrated
SQLite file through the app in-process (TestClient, no network), wall time; --format parquet
writes both as Parquet (a tenth of the CSV's bytes for the cycle file).  The issue's goal: the
cycle upload within 3x of the single-range one.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from app.config import Settings
from app.migrate import upgrade
from model.fleet import FleetConfig
from model.records import write_table
from model.spectra_fleet import SpectraFleetConfig, generate_spectra_fleet
from tests.app.conftest import serving


def _files(folder: Path, per_mix: int, suffix: str = ".csv") -> tuple[Path, Path, int]:
    spectra = generate_spectra_fleet(SpectraFleetConfig(FleetConfig(aircraft_per_mix=per_mix)))
    flights = spectra.fleet.flights_frame()
    flights["stress_range_mpa"] = spectra.paris_equivalent_mpa().reshape(-1)
    single = folder / f"flights{suffix}"
    write_table(flights, single)
    cycles = spectra.cycles_frame().drop(columns="mission")
    cycle_file = folder / f"cycles{suffix}"
    write_table(cycles, cycle_file)
    return single, cycle_file, len(cycles)


def _upload(folder: Path, name: str, path: Path) -> float:
    url = f"sqlite:///{folder / (name + '.db')}"
    upgrade(url)
    # a fleet's cycle file is millions of rows, past FLEETPINN_MAX_UPLOAD_ROWS' default
    settings = Settings(database_url=url, kernel="physics", max_upload_rows=100_000_000)
    with serving(settings) as client:
        started = time.perf_counter()
        with path.open("rb") as handle:
            answer = client.post("/flights/upload", files={"file": (path.name, handle)})
        elapsed = time.perf_counter() - started
    assert answer.status_code == 201, answer.text
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-mix", type=int, default=20)
    parser.add_argument(
        "--format", choices=("csv", "parquet"), default="csv", help="both files' format"
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        single, cycle_file, rows = _files(folder, args.per_mix, f".{args.format}")
        sizes = [round(path.stat().st_size / 1e6, 1) for path in (single, cycle_file)]
        single_s = _upload(folder, "single", single)
        cycles_s = _upload(folder, "cycles", cycle_file)
    print(
        json.dumps(
            {
                "tails": 3 * args.per_mix,
                "format": args.format,
                "megabytes": sizes,
                "cycle_rows": rows,
                "single_s": round(single_s, 2),
                "cycles_s": round(cycles_s, 2),
                "ratio": round(cycles_s / single_s, 2),
            }
        )
    )


if __name__ == "__main__":
    main()
