"""One control point's rows of the offline files, for `fit` and `predict`: the inspections
whose `location` column names it, and the recorded loads scaled to it.  A file holding
several locations' inspections is refused without `--location`: fitted or conditioned
together, each location's cracks would be read as one crack's (a wing root's and a lug's).
Needs no database: nothing here imports FastAPI or SQLAlchemy.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path

import pandas as pd

from app.cli.registry import CommandError
from app.default_location import DEFAULT_LOCATION
from model import records
from model.cycle_counting import FlightCycles
from model.record_validation import validate_inspections

# a cycle file's cycles by (tail, flight_id), as model.spectrum_files.load_flight_records reads them
Recorded = dict[tuple[str, str], FlightCycles]


def location_options(parser: argparse.ArgumentParser, use: str) -> None:
    """--location and --stress-factor; `use`: what the command does with the location."""
    parser.add_argument(
        "--location",
        default=None,
        help="a control point: only the inspections whose `location` column names it (rows "
        f"without one are the default location's); {use}",
    )
    parser.add_argument(
        "--stress-factor",
        type=float,
        default=1.0,
        help="the location's stress transfer factor: local stress per unit of the recorded one",
    )


def location_inspections(
    path: Path, known_tails: Iterable[str], location: str | None
) -> pd.DataFrame:
    """The file's inspections at `location` (None: the file must name one location at most),
    validated.  Raises CommandError naming the locations where it names several."""
    raw = records.read_table(path)
    given = raw["location"] if "location" in raw.columns else pd.Series("", index=raw.index)
    named = given.fillna("").astype(str).str.strip()
    named = named.where(named != "", DEFAULT_LOCATION)  # a blank cell: the default location
    if location is None:
        found = sorted(set(named))
        if len(found) > 1:
            raise CommandError(
                f"{path.name}: column location names {len(found)} locations "
                f"({', '.join(found)}): give --location NAME, one location at a time"
            )
        return validate_inspections(raw, path.name, known_tails)
    mine = raw[(named == location).to_numpy()].reset_index(drop=True)
    if mine.empty:
        raise CommandError(f"{path.name}: no inspection at location {location!r}")
    return validate_inspections(mine, path.name, known_tails)


def scaled_loads(
    flights: pd.DataFrame, recorded: Recorded | None, stress_factor: float
) -> tuple[pd.DataFrame, Recorded | None]:
    """The loads as the location sees them: every range times stress_factor (R unchanged).
    Raises CommandError for a factor that is not > 0."""
    if not stress_factor > 0:
        raise CommandError(f"--stress-factor must be > 0, got {stress_factor}")
    if stress_factor == 1.0:
        return flights, recorded
    flights = flights.assign(stress_range_mpa=flights["stress_range_mpa"] * stress_factor)
    if recorded is not None:
        recorded = {
            key: replace(cycles, stress_range_mpa=cycles.stress_range_mpa * stress_factor)
            for key, cycles in recorded.items()
        }
    return flights, recorded
