"""`fleetpinn spectrum`: stress time histories to the per-flight cycle file, offline.

Reads a histories file (model.spectrum_files: tail, flight_id, flown_at, stress_mpa, optional
mission; one row per point, in order within each flight), counts every flight into cycles by
rainflow (ASTM E1049 half cycles, model.cycle_counting) and writes the cycle file POST
/flights/upload takes (one row per cycle: stress_range_mpa, load_ratio, count).  Nothing here
imports FastAPI, SQLAlchemy or PyTorch's models.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from app.cli.registry import CommandError, command
from model import records
from model.spectrum_files import histories_to_cycles


def _arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--histories", type=Path, required=True, help="stress histories .csv or .parquet"
    )
    parser.add_argument("--out", type=Path, required=True, help="cycle file to write")


@command("spectrum", "count stress histories into the per-flight cycle file", _arguments)
def spectrum(args: argparse.Namespace) -> int:
    frame = records.read_table(args.histories)
    cycles = histories_to_cycles(frame, args.histories.name)
    try:
        records.write_table(cycles, args.out)
    except OSError as exc:
        raise CommandError(f"{args.out.name}: cannot write: {exc.strerror or exc}") from exc
    flights = cycles.groupby(["tail", "flight_id"]).ngroups
    print(f"{len(cycles)} cycles of {flights} flights -> {args.out}")
    return 0
