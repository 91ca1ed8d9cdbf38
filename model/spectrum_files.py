"""Record files of load spectra: stress time histories in, the per-flight cycle file out, and the
cycle file read back as flights with their cycles.

HISTORIES (CSV or Parquet, `fleetpinn spectrum`): tail, flight_id, flown_at, stress_mpa, optional
mission; one row per point of a flight's stress history (peaks and valleys, or a sampled
series), in order within the flight.  CYCLES (what `spectrum` writes, and what POST
/flights/upload takes besides the one-range flights file): tail, flight_id, flown_at,
stress_range_mpa, load_ratio, count, optional mission; one row per cycle (model.cycle_counting).
Errors are RecordErrors naming the file, the row (of the flight's first point) and the column.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from model.cycle_counting import CycleError, FlightCycles, from_history
from model.growth_laws import GROWTH_LAWS, CycleSpectrum, GrowthConstants
from model.integrate import LoadHistory
from model.record_validation import validate_flights
from model.records import RecordError, read_table
from model.training_data import TrainingData

HISTORY_COLUMNS = ("tail", "flight_id", "flown_at", "stress_mpa")
CYCLE_COLUMNS = ("tail", "flight_id", "flown_at", "stress_range_mpa", "load_ratio", "count")


def _require(frame: pd.DataFrame, columns: tuple[str, ...], source: str) -> None:
    for column in columns:
        if column not in frame.columns:
            raise RecordError(source, None, column, "missing column")


def _flights(frame: pd.DataFrame) -> list[tuple[tuple[str, str], np.ndarray]]:
    """(tail, flight_id) and its rows' positions, in the order flights first appear."""
    keys = frame["tail"].astype(str) + "\x00" + frame["flight_id"].astype(str)
    codes, uniques = pd.factorize(keys)
    order = np.argsort(codes, kind="stable")
    bounds = np.searchsorted(codes[order], np.arange(len(uniques) + 1))
    out = []
    for i, key in enumerate(uniques):
        tail, flight_id = str(key).split("\x00", 1)
        out.append(((tail, flight_id), order[bounds[i] : bounds[i + 1]]))
    return out


def histories_to_cycles(frame: pd.DataFrame, source: str) -> pd.DataFrame:
    """The cycle file (CYCLE_COLUMNS, mission where given) of a histories file."""
    _require(frame, HISTORY_COLUMNS, source)
    stress = pd.to_numeric(frame["stress_mpa"], errors="coerce").to_numpy(dtype=np.float64)
    bad = np.flatnonzero(~np.isfinite(stress))
    if len(bad):
        row = int(bad[0])
        raise RecordError(
            source,
            row + 1,
            "stress_mpa",
            f"must be a finite number, got {frame['stress_mpa'].iloc[row]!r}",
        )
    parts = []
    for (tail, flight_id), rows in _flights(frame):
        try:
            cycles = from_history(stress[rows].tolist(), "stress_mpa")
        except CycleError as exc:
            raise RecordError(
                source, int(rows[0]) + 1, exc.field, f"flight {flight_id!r} of {tail!r}: {exc}"
            ) from exc
        first = frame.iloc[int(rows[0])]
        part = pd.DataFrame(
            {
                "tail": tail,
                "flight_id": flight_id,
                "flown_at": first["flown_at"],
                "stress_range_mpa": cycles.stress_range_mpa,
                "load_ratio": cycles.load_ratio,
                "count": cycles.count,
            }
        )
        if "mission" in frame.columns:
            part["mission"] = first["mission"]
        parts.append(part)
    columns = [*CYCLE_COLUMNS, *(["mission"] if "mission" in frame.columns else [])]
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=columns)


def cycles_to_flights(
    frame: pd.DataFrame, source: str, growth_law: str, constants: GrowthConstants
) -> tuple[pd.DataFrame, dict[tuple[str, str], FlightCycles]]:
    """The flights of a cycle file (tail, flight_id, flown_at, stress_range_mpa: the cycles'
    damage-equivalent range under the law, mission) and each flight's cycles by (tail,
    flight_id).  A flight's rows must agree on flown_at (and mission)."""
    _require(frame, CYCLE_COLUMNS, source)
    values = {}
    for column in ("stress_range_mpa", "load_ratio", "count"):
        numbers = pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=np.float64)
        bad = np.flatnonzero(~np.isfinite(numbers))
        if len(bad):
            row = int(bad[0])
            got = frame[column].iloc[row]
            raise RecordError(source, row + 1, column, f"must be a finite number, got {got!r}")
        values[column] = numbers
    for column, ok, rule in (
        ("stress_range_mpa", values["stress_range_mpa"] > 0, "> 0"),
        ("load_ratio", values["load_ratio"] < 1, "< 1"),
        ("count", values["count"] > 0, "> 0"),
    ):
        bad = np.flatnonzero(~ok)
        if len(bad):
            row = int(bad[0])
            raise RecordError(source, row + 1, column, f"must be {rule}, got {values[column][row]}")
    codes = frame.groupby(["tail", "flight_id"], sort=False).ngroup().to_numpy()
    flights = int(codes.max(initial=-1)) + 1
    order = np.argsort(codes, kind="stable")
    starts = np.searchsorted(codes[order], np.arange(flights + 1))
    first = order[starts[:-1]]  # each flight's first row
    tails = frame["tail"].to_numpy()[first].astype(str)
    flight_ids = frame["flight_id"].to_numpy()[first].astype(str)
    times = pd.factorize(frame["flown_at"])[0]
    differs = np.flatnonzero(times != times[first][codes])
    if len(differs):
        row = int(differs[0])
        tail, flight_id = tails[codes[row]], flight_ids[codes[row]]
        raise RecordError(
            source,
            row + 1,
            "flown_at",
            f"flight {flight_id!r} of {tail!r}: its cycles' rows differ in flown_at",
        )
    # every flight's cycles side by side, (1, flights, most cycles), in one reduction
    position = np.empty(len(codes), dtype=np.int64)
    position[order] = np.arange(len(codes)) - starts[codes[order]]
    width = int(np.diff(starts).max(initial=1))
    padded = np.zeros((3, 1, flights, width))
    for c, column in enumerate(("stress_range_mpa", "load_ratio", "count")):
        padded[c, 0, codes, position] = values[column]
    spectrum = CycleSpectrum(*(torch.from_numpy(padded[c]) for c in range(3)))
    ranges = GROWTH_LAWS[growth_law].equivalent_range(spectrum, constants)[0].numpy()
    out = pd.DataFrame(
        {
            "tail": tails,
            "flight_id": flight_ids,
            "flown_at": frame["flown_at"].iloc[first].reset_index(drop=True),
            "stress_range_mpa": ranges,
        }
    )
    if "mission" in frame.columns:
        out["mission"] = frame["mission"].iloc[first].reset_index(drop=True)
    # each flight's cycles: views of its row of the padded channels
    sizes = np.diff(starts).tolist()
    keys = zip(tails.tolist(), flight_ids.tolist(), strict=True)
    rows = padded[:, 0]
    recorded = {
        key: FlightCycles(rows[0, f, :n], rows[1, f, :n], rows[2, f, :n])
        for f, (key, n) in enumerate(zip(keys, sizes, strict=True))
    }
    return out, recorded


def load_flight_records(
    path: str | Path, growth_law: str, constants: GrowthConstants
) -> tuple[pd.DataFrame, dict[tuple[str, str], FlightCycles] | None]:
    """A flights file or a cycle file (it has a load_ratio column), validated as flights (a
    cycle file's flights carry their damage-equivalent range under the law), and the cycles by
    (tail, flight_id) where it was a cycle file."""
    frame, name = read_table(path), Path(path).name
    if "load_ratio" not in frame.columns:
        return validate_flights(frame, name), None
    flights, recorded = cycles_to_flights(frame, name, growth_law, constants)
    return validate_flights(flights, name), recorded


def with_cycles(
    data: TrainingData,
    recorded: dict[tuple[str, str], FlightCycles],
    growth_law: str,
    constants: GrowthConstants,
) -> TrainingData:
    """`data` whose loads carry every flight's recorded cycles (reduced under the law), so that
    a fit can learn the law's exponents from them (model.paris_calibration)."""
    ordered = data.flights
    keys = zip(ordered["tail"].astype(str), ordered["flight_id"].astype(str), strict=True)
    flights = [recorded[key] for key in keys]
    width = max((len(f) for f in flights), default=1)
    rows, steps = data.loads.stress_range_mpa.shape
    padded = np.zeros((3, rows, steps, width))
    aircraft = ordered["aircraft"].to_numpy()
    position = ordered["flight"].to_numpy() - 1
    for i, flight in enumerate(flights):
        for c, values in enumerate(flight.columns):
            padded[c, aircraft[i], position[i], : len(flight)] = values
    spectrum = CycleSpectrum(*(torch.from_numpy(padded[c]) for c in range(3)))
    loads = LoadHistory.from_cycles(spectrum, data.loads.lengths, growth_law, constants)
    return replace(data, loads=loads)
