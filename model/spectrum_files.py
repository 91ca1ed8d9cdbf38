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

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
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


@dataclass(frozen=True)
class CycleTable:
    """Every flight's cycles back to back, flights in the order of their flights frame.

    table: (cycles, 3) float64, C-contiguous: stress_range_mpa, load_ratio, count per cycle
    (FlightCycles.packed's layout, so a flight's stored blob is a slice of its bytes);
    starts: (flights + 1,) flight f's cycles are table[starts[f]:starts[f + 1]].
    """

    table: np.ndarray
    starts: np.ndarray

    def flight(self, f: int) -> FlightCycles:
        rows = self.table[self.starts[f] : self.starts[f + 1]]
        return FlightCycles(rows[:, 0], rows[:, 1], rows[:, 2])

    def block(self, flights: np.ndarray) -> tuple[bytes, np.ndarray]:
        """`flights`' cycles back to back as FlightCycles.packed bytes, and (len(flights) + 1,)
        their starts in it (in cycles): one slice of the buffer where the flights follow each
        other in it, as a file's flights of one tail do; else gathered."""
        first, last = self.starts[flights], self.starts[flights + 1]
        sizes = last - first
        starts = np.concatenate(([0], np.cumsum(sizes))).astype(np.int64)
        if len(flights) and (first[1:] == last[:-1]).all():
            rows = self.table[first[0] : last[-1]]
        else:
            rows = self.table[np.repeat(first - starts[:-1], sizes) + np.arange(starts[-1])]
        return rows.astype("<f8", copy=False).tobytes(), starts


def _flight_codes(frame: pd.DataFrame) -> np.ndarray:
    """(rows,) each row's flight, numbered in the order flights first appear.  A file written
    flight by flight needs no hashing of every row: a flight starts where (tail, flight_id)
    differs from the row before (Arrow's vectorised compare), and only those first rows' keys
    are checked to be distinct (a tenth of the rows); any other order takes pandas' group-by."""
    rows = len(frame)
    if rows == 0:
        return np.zeros(0, dtype=np.int64)
    same = np.ones(rows - 1, dtype=bool)  # row i + 1 has row i's tail and flight_id
    for column in ("tail", "flight_id"):
        keys = pa.array(frame[column], from_pandas=True)
        if isinstance(keys, pa.ChunkedArray):
            keys = keys.combine_chunks()
        changed = pc.fill_null(pc.not_equal(keys.slice(1), keys.slice(0, rows - 1)), True)
        same &= ~changed.to_numpy(zero_copy_only=False)
    starts = np.concatenate(([True], ~same))
    first = np.flatnonzero(starts)
    if not frame[["tail", "flight_id"]].iloc[first].duplicated().any():
        return np.cumsum(starts) - 1
    return frame.groupby(["tail", "flight_id"], sort=False).ngroup().to_numpy()


def _comparable(times: pd.Series) -> np.ndarray:
    """(rows,) integers equal exactly where the times are (the datetime's own ticks; a code
    per distinct value for any other column type)."""
    if isinstance(times.dtype, pd.DatetimeTZDtype) or times.dtype.kind == "M":
        return np.asarray(times.array.asi8)
    return pd.factorize(times)[0]


def cycle_table(
    frame: pd.DataFrame, source: str, growth_law: str, constants: GrowthConstants
) -> tuple[pd.DataFrame, CycleTable]:
    """The flights of a cycle file (tail, flight_id, flown_at, stress_range_mpa: the cycles'
    damage-equivalent range under the law, mission) and their cycles, row f of the one the
    cycles of flight f.  A flight's rows must agree on flown_at (and mission)."""
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
    codes = _flight_codes(frame)
    flights = int(codes.max(initial=-1)) + 1
    # a file written flight by flight (as `spectrum` writes it) is in order already
    in_order = bool((np.diff(codes) >= 0).all())
    order = np.arange(len(codes)) if in_order else np.argsort(codes, kind="stable")
    sorted_codes = codes if in_order else codes[order]
    starts = np.searchsorted(sorted_codes, np.arange(flights + 1))
    first = order[starts[:-1]]  # each flight's first row
    # the first rows' keys only: converting every row's (arrow) strings took 0.3 s of 3.4 M
    tails = frame["tail"].iloc[first].to_numpy(dtype=object).astype(str)
    flight_ids = frame["flight_id"].iloc[first].to_numpy(dtype=object).astype(str)
    times = _comparable(frame["flown_at"])
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
    channels = ("stress_range_mpa", "load_ratio", "count")
    columns = [values[column] if in_order else values[column][order] for column in channels]
    table = np.stack(columns, axis=1)  # (cycles, 3)
    law = GROWTH_LAWS[growth_law]
    ranges = law.flights_equivalent_range(table, starts, constants)
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
    return out, CycleTable(table, starts)


def cycles_to_flights(
    frame: pd.DataFrame, source: str, growth_law: str, constants: GrowthConstants
) -> tuple[pd.DataFrame, dict[tuple[str, str], FlightCycles]]:
    """cycle_table's flights, and each flight's cycles by (tail, flight_id)."""
    out, cycles = cycle_table(frame, source, growth_law, constants)
    keys = zip(out["tail"].tolist(), out["flight_id"].tolist(), strict=True)
    return out, {key: cycles.flight(f) for f, key in enumerate(keys)}


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
