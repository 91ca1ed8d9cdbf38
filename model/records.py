"""Long-format flight and inspection records: the file contract of the CLI and the HTTP upload.

FLIGHTS (CSV or Parquet), one row per flight:
    tail, flight_id, flown_at (ISO 8601; naive times are UTC), stress_range_mpa (> 0),
    optional mission.
INSPECTIONS, one row per crack measurement:
    tail, inspection_id, inspected_at (ISO 8601; naive times are UTC), crack_length_m (> 0).
    Optional columns (a file without any of them reads exactly as before):
    detected (true/false, blank: true): false = nothing found, crack_length_m then blank and
    either detection_threshold_m (> 0, a hard threshold) or pod_a50_m and pod_a90_m (a
    log-normal probability-of-detection curve, pod_a90_m > pod_a50_m > 0);
    repaired (true/false, blank: false) with crack_after_repair_m (> 0) iff repaired: the crack
    restarts from crack_after_repair_m after the inspection.

A tail's flights are ordered by flown_at, ties broken by flight_id, so the order never depends on
file order or storage order.  An inspection observes the crack after every flight of its tail
flown strictly before inspected_at.  (tail, flight_id) and (tail, inspection_id) are keys: an
exact repeat of a row is harmless and collapsed; the same key with other values is an error.

Rows in errors and in the index of a validated frame are 1-based data rows: the header line is
not counted, so row 1 is the first line after the header (line 2 of a CSV file).

This module holds the contract's names and the file reading and writing; its error is
model/record_errors.py's, the shape bounds checked before a file is parsed
model/record_bounds.py's, the checks of values model/record_validation.py's (validate_*,
load_*), the mapping to model inputs model/training_data.py's (assemble).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.csv as pa_csv

from model.record_bounds import check_csv, check_parquet
from model.record_errors import RecordError

FLIGHT_COLUMNS = ("tail", "flight_id", "flown_at", "stress_range_mpa")
FLIGHT_OPTIONAL_COLUMNS = ("mission",)
INSPECTION_COLUMNS = ("tail", "inspection_id", "inspected_at", "crack_length_m")
INSPECTION_OPTIONAL_COLUMNS = (
    "detected",
    "detection_threshold_m",
    "pod_a50_m",
    "pod_a90_m",
    "repaired",
    "crack_after_repair_m",
)
_TEXT_COLUMNS = ("tail", "flight_id", "inspection_id", "mission")


def read_table(
    path: str | Path, *, max_rows: int | None = None, max_bytes: int | None = None
) -> pd.DataFrame:
    """Read a record file by suffix (.csv or .parquet) without interpreting its values yet.

    Its shape is checked before it is parsed (model.record_bounds): line lengths, columns and
    fields per row of a CSV; columns of a Parquet file, and where given its rows (max_rows, of
    either kind) and decompressed bytes (max_bytes) from its footer.  Identifier columns are
    read as text (a tail "007" stays "007"); other columns keep whatever type the reader
    infers, and validate_* normalises them.  Raises RecordError for an unknown suffix, a missing
    or unreadable file, or a shape out of those bounds (naming the row where it is one row's).
    """
    path = Path(path)
    source = path.name
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".parquet"):
        raise RecordError(source, None, None, f"unknown file type {suffix!r}; use .csv or .parquet")
    if not path.is_file():
        raise RecordError(source, None, None, f"no such file: {path}")
    if suffix == ".csv":
        check_csv(path, source, max_rows)
    else:
        check_parquet(path, source, max_rows, max_bytes)
    try:
        frame = _read_csv(path, source) if suffix == ".csv" else pd.read_parquet(path)
    except RecordError:
        raise
    except Exception as exc:  # reader errors carry no stable type; report them on the file
        raise RecordError(source, None, None, f"cannot read file: {exc}") from exc
    frame.columns = [str(c).strip() for c in frame.columns]
    return frame


def write_table(frame: pd.DataFrame, path: str | Path) -> None:
    """Write a frame as .csv or .parquet (by suffix), the inverse of read_table.

    CSV times are ISO 8601 UTC ("2020-01-01T06:00:00Z", fractional seconds only where present),
    each distinct time formatted once, and the file is written by pyarrow: a 2 M-row fleet takes
    about a second.  Raises RecordError for another suffix; OSError if the file cannot be written.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".parquet":
        frame.to_parquet(path, index=False)
        return
    if suffix != ".csv":
        raise RecordError(
            path.name, None, None, f"unknown file type {suffix!r}; use .csv or .parquet"
        )
    columns = {}
    for name, column in frame.items():
        if isinstance(column.dtype, pd.DatetimeTZDtype) or pd.api.types.is_datetime64_dtype(column):
            columns[str(name)] = _iso_utc(column)
    table = pa.Table.from_pandas(frame.assign(**columns), preserve_index=False)
    pa_csv.write_csv(table, path)


def _iso_utc(times: pd.Series) -> np.ndarray:
    utc = times.dt.tz_localize("UTC") if times.dt.tz is None else times.dt.tz_convert("UTC")
    codes, distinct = pd.factorize(utc)
    index = pd.DatetimeIndex(distinct)
    fractional = (index.as_unit("ns").asi8 % 1_000_000_000 != 0).any()
    text = index.strftime("%Y-%m-%dT%H:%M:%S.%fZ" if fractional else "%Y-%m-%dT%H:%M:%SZ")
    formatted = np.append(np.asarray(text, dtype=object), "")  # code -1 (NaT) -> blank
    return formatted[codes]


def _read_csv(path: Path, source: str) -> pd.DataFrame:
    text_dtypes = dict.fromkeys(_TEXT_COLUMNS, "str")
    try:
        # keep_default_na=False: "NA" is a valid tail and a blank cell must stay visible as "".
        return pd.read_csv(path, dtype=text_dtypes, keep_default_na=False, engine="pyarrow")
    except pd.errors.EmptyDataError as exc:
        raise RecordError(source, None, None, "empty file (no header line)") from exc
    except pd.errors.ParserError:
        # The fast reader names no line; the C reader does.  Re-read only on this error path.
        try:
            return pd.read_csv(path, dtype=str, keep_default_na=False)
        except pd.errors.ParserError as c_exc:
            match = re.search(r"line (\d+), saw (\d+)", str(c_exc))
            if match is None:
                raise RecordError(source, None, None, f"cannot parse CSV: {c_exc}") from c_exc
            line, saw = int(match.group(1)), int(match.group(2))
            raise RecordError(
                source, line - 1, None, f"has {saw} fields, more than the header's"
            ) from c_exc
