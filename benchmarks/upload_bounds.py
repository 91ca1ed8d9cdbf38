"""Hostile uploads refused from their shape, before they are parsed (issue 42).

    .venv/bin/python -m benchmarks.upload_bounds

Three uploads through an in-process server on a fresh SQLite file: the contract header and one
row of 40,000 extra fields (80 kB), the same with 1 M (2 MB), and a zstd Parquet file of 50 M
identical rows (~750 kB; 50 row groups of 1 M dictionary-encoded rows).  Each is printed with
its status, the wall time of the request and the process's peak RSS growth over it (ru_maxrss,
so a growth shows only where the request set a new peak).
"""

from __future__ import annotations

import resource
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from tests.app.conftest import serving, settings_in

HEADER = "tail,flight_id,flown_at,stress_range_mpa\n"
ROW = "H1,W1,2024-03-01T00:00:00Z,100"


def _bomb(folder: Path, row_groups: int = 50, rows: int = 1_000_000) -> bytes:
    codes = pa.array(np.zeros(rows, dtype=np.int32))
    table = pa.table(
        {
            "tail": pa.DictionaryArray.from_arrays(codes, pa.array(["B1"])),
            "flight_id": pa.DictionaryArray.from_arrays(codes, pa.array(["F1"])),
            "flown_at": pa.DictionaryArray.from_arrays(codes, pa.array(["2024-01-01T00:00:00Z"])),
            "stress_range_mpa": pa.array(np.full(rows, 100.0)),
        }
    )
    path = folder / "bomb.parquet"
    with pq.ParquetWriter(path, table.schema, compression="zstd") as writer:
        for _ in range(row_groups):
            writer.write_table(table)
    return path.read_bytes()


def _peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main() -> None:
    folder = Path(tempfile.mkdtemp())
    uploads = {
        "wide.csv": (HEADER + ROW + ",1" * 40_000 + "\n").encode(),
        "huge.csv": (HEADER + ROW + ",1" * 1_000_000 + "\n").encode(),
        "bomb.parquet": _bomb(folder),
    }
    quiet = settings_in(folder).model_copy(update={"answers_ahead": False, "run_worker": False})
    with serving(quiet) as client:
        for name, body in uploads.items():
            before, started = _peak_mib(), time.monotonic()
            answer = client.post("/flights/upload", files={"file": (name, body, "text/csv")})
            seconds = time.monotonic() - started
            reason = str(answer.json().get("reason", ""))[:90]
            print(
                f"{name:<13} {len(body):>9} bytes  {answer.status_code}  {seconds:.3f} s  "
                f"peak +{_peak_mib() - before:.0f} MiB  {reason}"
            )


if __name__ == "__main__":
    main()
