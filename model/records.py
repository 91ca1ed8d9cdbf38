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
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.csv as pa_csv
import torch
from torch import Tensor

from model.integrate import LoadHistory, Observations

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
_TRUE = frozenset({"true", "1", "yes", "t", "y"})
_FALSE = frozenset({"false", "0", "no", "f", "n"})
_TEXT_COLUMNS = ("tail", "flight_id", "inspection_id", "mission")
_FIRST_NS = pd.Timestamp("1678-01-01", tz="UTC")
_LAST_NS = pd.Timestamp("2262-01-01", tz="UTC")


class RecordError(ValueError):
    """A bad record file or frame, located for the person who has to fix it.

    source: file name (or a label such as "flights"); row: 1-based data row, header excluded
    (None when the problem is not one row's, e.g. a missing column); column: the column name or
    None; reason: what is wrong, with the offending value.  str() reads e.g.
    "flights.csv row 12, column stress_range_mpa: must be > 0, got -3".
    """

    def __init__(self, source: str, row: int | None, column: str | None, reason: str) -> None:
        self.source, self.row, self.column, self.reason = source, row, column, reason
        message = source if row is None else f"{source} row {row}"
        if column is not None:
            message += f", column {column}"
        super().__init__(f"{message}: {reason}")

    def __reduce__(self) -> tuple[type[RecordError], tuple[str, int | None, str | None, str]]:
        # keeps the error intact across processes (the default would call __init__(message))
        return (RecordError, (self.source, self.row, self.column, self.reason))


def read_table(path: str | Path) -> pd.DataFrame:
    """Read a record file by suffix (.csv or .parquet) without interpreting its values yet.

    Identifier columns are read as text (a tail "007" stays "007"); other columns keep whatever
    type the reader infers, and validate_* normalises them.  Raises RecordError for an unknown
    suffix, a missing or unreadable file, or a CSV line with the wrong number of fields.
    """
    path = Path(path)
    source = path.name
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".parquet"):
        raise RecordError(source, None, None, f"unknown file type {suffix!r}; use .csv or .parquet")
    if not path.is_file():
        raise RecordError(source, None, None, f"no such file: {path}")
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


class _Problems:
    """Collects vectorised checks and raises the first bad row (ties: column order)."""

    def __init__(self, source: str, columns: tuple[str, ...]) -> None:
        self.source, self.columns = source, columns
        self.found: list[tuple[int, int, str, Callable[[int], str]]] = []

    def check(self, bad: np.ndarray, column: str, reason: Callable[[int], str]) -> None:
        if bad.any():
            position = int(np.argmax(bad))
            self.found.append((position, self.columns.index(column), column, reason))

    def raise_first(self) -> None:
        if self.found:
            position, _, column, reason = min(self.found, key=lambda f: (f[0], f[1]))
            raise RecordError(self.source, position + 1, column, reason(position))


def _show(value: object) -> str:
    if isinstance(value, float | np.floating):
        return f"{float(value):g}"
    return repr(value)


def _require_columns(df: pd.DataFrame, source: str, required: tuple[str, ...]) -> None:
    for column in required:
        if column not in df.columns:
            found = ", ".join(map(str, df.columns)) or "none"
            raise RecordError(source, None, column, f"missing column (columns found: {found})")


def _text(series: pd.Series) -> pd.Series:
    """Stripped text with "" for missing cells."""
    return series.astype("str").fillna("").str.strip()


def _check_text(problems: _Problems, text: pd.Series, column: str) -> None:
    problems.check((text == "").to_numpy(), column, lambda _: "must not be blank")


def _positive_numbers(problems: _Problems, series: pd.Series, column: str) -> pd.Series:
    """float64 values; blank, non-numeric, non-finite and non-positive cells are problems."""
    if pd.api.types.is_numeric_dtype(series) and not pd.api.types.is_bool_dtype(series):
        values = series.astype("float64")
        blank = values.isna().to_numpy()
        problems.check(blank, column, lambda _: "must not be blank")
    else:
        text = _text(series)
        values = pd.to_numeric(text, errors="coerce").astype("float64")
        blank = (text == "").to_numpy()
        problems.check(blank, column, lambda _: "must not be blank")
        not_number = values.isna().to_numpy() & ~blank
        problems.check(not_number, column, lambda i: f"must be a number, got {text.iloc[i]!r}")
    array = values.to_numpy()
    with np.errstate(invalid="ignore"):
        problems.check(np.isinf(array), column, lambda i: f"must be finite, got {_show(array[i])}")
        problems.check(array <= 0, column, lambda i: f"must be > 0, got {_show(array[i])}")
    return values


def _utc_times(problems: _Problems, series: pd.Series, column: str) -> pd.Series:
    """datetime64[ns, UTC]; naive times are taken as UTC, others converted to UTC."""
    if isinstance(series.dtype, pd.DatetimeTZDtype):
        times = series.dt.tz_convert("UTC")
        problems.check(times.isna().to_numpy(), column, lambda _: "must not be blank")
    elif pd.api.types.is_datetime64_dtype(series):
        times = series.dt.tz_localize("UTC")
        problems.check(times.isna().to_numpy(), column, lambda _: "must not be blank")
    else:
        text = _text(series)
        times = pd.to_datetime(text, utc=True, format="ISO8601", errors="coerce")
        blank = (text == "").to_numpy()
        problems.check(blank, column, lambda _: "must not be blank")
        unparsed = times.isna().to_numpy() & ~blank
        problems.check(
            unparsed, column, lambda i: f"must be an ISO 8601 time, got {text.iloc[i]!r}"
        )
    outside = ((times < _FIRST_NS) | (times >= _LAST_NS)).to_numpy()
    problems.check(
        outside, column, lambda i: f"must lie in years 1678-2261, got {times.iloc[i].isoformat()}"
    )
    problems.raise_first()
    return times.dt.as_unit("ns")


def _collapse_duplicates(df: pd.DataFrame, source: str, id_column: str) -> pd.DataFrame:
    """Drop exact repeats of a row; raise on a (tail, id) key reused with other values.

    df: normalised frame indexed by source row.  Only rows whose id occurs more than once are
    compared on (tail, id) and then on all values, so unique ids cost one hash of the id column.
    """
    candidates = df[df[id_column].duplicated(keep=False).to_numpy()]
    candidates = candidates[candidates.duplicated(["tail", id_column], keep=False).to_numpy()]
    if candidates.empty:
        return df
    exact = candidates.duplicated(keep="first").to_numpy()
    distinct = candidates[~exact]
    conflict = distinct.duplicated(["tail", id_column], keep="first").to_numpy()
    if conflict.any():
        row = int(distinct.index[int(np.argmax(conflict))])
        tail, ident = distinct.loc[row, "tail"], distinct.loc[row, id_column]
        same = distinct[(distinct["tail"] == tail) & (distinct[id_column] == ident)]
        raise RecordError(
            source,
            row,
            id_column,
            f"{id_column} {ident!r} of tail {tail!r} repeats row {int(same.index[0])} "
            "with different values",
        )
    return df.drop(index=candidates.index[exact])


def validate_flights(df: pd.DataFrame, source: str = "flights") -> pd.DataFrame:
    """Check and normalise a flights frame (see the module docstring for the contract).

    Returns columns tail (str), flight_id (str), flown_at (datetime64[ns, UTC]),
    stress_range_mpa (float64), mission (object: str or None), indexed by the 1-based source row
    ("row"), exact repeats collapsed.  Extra columns are dropped.  Raises RecordError naming the
    first bad row and column: missing column, blank tail or flight_id, non-numeric, non-finite or
    non-positive stress, blank or unparseable time, a (tail, flight_id) repeated with other values.
    """
    columns = FLIGHT_COLUMNS + FLIGHT_OPTIONAL_COLUMNS
    _require_columns(df, source, FLIGHT_COLUMNS)
    problems = _Problems(source, columns)
    tail, flight_id = _text(df["tail"]), _text(df["flight_id"])
    _check_text(problems, tail, "tail")
    _check_text(problems, flight_id, "flight_id")
    stress = _positive_numbers(problems, df["stress_range_mpa"], "stress_range_mpa")
    flown_at = _utc_times(problems, df["flown_at"], "flown_at")
    if "mission" in df.columns:
        mission_text = _text(df["mission"])
        mission_values = mission_text.to_numpy(dtype=object)
        mission_values[(mission_text == "").to_numpy()] = None
    else:
        mission_values = np.full(len(df), None, dtype=object)
    out = pd.DataFrame(
        {
            "tail": tail.array,
            "flight_id": flight_id.array,
            "flown_at": flown_at.array,
            "stress_range_mpa": stress.array,
        },
        index=pd.RangeIndex(1, len(df) + 1, name="row"),
    )
    # assigned after construction: the constructor would infer str and turn None into NaN
    out["mission"] = pd.Series(mission_values, index=out.index, dtype=object)
    return _collapse_duplicates(out, source, "flight_id")


def validate_inspections(
    df: pd.DataFrame, source: str = "inspections", known_tails: Iterable[str] | None = None
) -> pd.DataFrame:
    """Check and normalise an inspections frame (see the module docstring for the contract).

    Returns columns tail (str), inspection_id (str), inspected_at (datetime64[ns, UTC]),
    crack_length_m (float64), indexed by the 1-based source row ("row"), exact repeats collapsed;
    when the frame has any optional column, also detected (bool), detection_threshold_m,
    pod_a50_m, pod_a90_m (float64, NaN where not given), repaired (bool) and
    crack_after_repair_m (float64, NaN unless repaired), and crack_length_m is NaN where
    detected is false.
    Raises RecordError naming the first bad row and column: missing column, blank tail or id,
    non-numeric, non-finite or non-positive crack, blank or unparseable time, a repeated
    (tail, inspection_id) with other values, or (known_tails given) a tail not among them; with
    optional columns also a crack given where detected is false, a non-detection without
    detection_threshold_m or pod_a50_m/pod_a90_m (or with both), pod_a90_m <= pod_a50_m, or
    crack_after_repair_m given iff not repaired.
    """
    _require_columns(df, source, INSPECTION_COLUMNS)
    optional = any(c in df.columns for c in INSPECTION_OPTIONAL_COLUMNS)
    problems = _Problems(source, INSPECTION_COLUMNS + INSPECTION_OPTIONAL_COLUMNS)
    tail, inspection_id = _text(df["tail"]), _text(df["inspection_id"])
    _check_text(problems, tail, "tail")
    if known_tails is not None:
        unknown = ~tail.isin(list(known_tails)).to_numpy() & (tail != "").to_numpy()
        problems.check(
            unknown, "tail", lambda i: f"unknown tail {tail.iloc[i]!r} (no flights recorded)"
        )
    _check_text(problems, inspection_id, "inspection_id")
    values: dict[str, Any]
    if optional:
        values = dict(_optional_inspection_columns(problems, df))
    else:
        values = {
            "crack_length_m": _positive_numbers(problems, df["crack_length_m"], "crack_length_m")
        }
    inspected_at = _utc_times(problems, df["inspected_at"], "inspected_at")
    columns: dict[str, object] = {
        "tail": tail.array,
        "inspection_id": inspection_id.array,
        "inspected_at": inspected_at.array,
        "crack_length_m": np.asarray(values.pop("crack_length_m"), dtype=np.float64),
        **values,
    }
    out = pd.DataFrame(columns, index=pd.RangeIndex(1, len(df) + 1, name="row"))
    return _collapse_duplicates(out, source, "inspection_id")


def _flags(problems: _Problems, df: pd.DataFrame, column: str, default: bool) -> np.ndarray:
    """bool (rows,) from true/false/1/0/yes/no cells; blank or missing column: default."""
    if column not in df.columns:
        return np.full(len(df), default)
    series = df[column]
    if pd.api.types.is_bool_dtype(series):
        return series.to_numpy(dtype=bool)
    text = _text(series).str.lower().replace({"nan": "", "none": "", "<na>": "", "1.0": "1"})
    text = text.replace({"0.0": "0"})
    known = text.isin(_TRUE | _FALSE | {""}).to_numpy()
    problems.check(~known, column, lambda i: f"must be true or false, got {series.iloc[i]!r}")
    return np.where(text == "", default, text.isin(_TRUE)).astype(bool)


def _optional_numbers(problems: _Problems, df: pd.DataFrame, column: str) -> np.ndarray:
    """float64 (rows,): given cells checked as positive numbers, NaN where blank or missing."""
    if column not in df.columns:
        return np.full(len(df), np.nan)
    series = df[column]
    blank = series.isna().to_numpy() | (_text(series) == "").to_numpy()
    values = np.full(len(df), np.nan)
    rows = np.flatnonzero(~blank)
    if len(rows):
        sub = _Problems(problems.source, problems.columns)
        checked = _positive_numbers(sub, series.iloc[rows].reset_index(drop=True), column)
        for position, index, name, reason in sub.found:
            problems.found.append((int(rows[position]), index, name, _at(reason, position)))
        values[rows] = checked.to_numpy()
    return values


def _at(reason: Callable[[int], str], position: int) -> Callable[[int], str]:
    """`reason` of a sub-frame's row `position`, whatever row the caller asks about."""
    return lambda _: reason(position)


def _optional_inspection_columns(problems: _Problems, df: pd.DataFrame) -> dict[str, np.ndarray]:
    """The crack, non-detection and repair columns of a frame with optional columns."""
    detected = _flags(problems, df, "detected", True)
    crack = _optional_numbers(problems, df, "crack_length_m")
    given = ~np.isnan(crack)
    problems.check(detected & ~given, "crack_length_m", lambda _: "required where detected")
    problems.check(
        ~detected & given, "crack_length_m", lambda _: "must be blank where detected is false"
    )
    threshold = _optional_numbers(problems, df, "detection_threshold_m")
    a50 = _optional_numbers(problems, df, "pod_a50_m")
    a90 = _optional_numbers(problems, df, "pod_a90_m")
    has_t, has_50, has_90 = ~np.isnan(threshold), ~np.isnan(a50), ~np.isnan(a90)
    problems.check(
        ~detected & ~has_t & ~has_50,
        "detection_threshold_m",
        lambda _: "required where detected is false (or pod_a50_m and pod_a90_m)",
    )
    problems.check(
        has_t & (has_50 | has_90),
        "detection_threshold_m",
        lambda _: "give either detection_threshold_m or pod_a50_m/pod_a90_m, not both",
    )
    problems.check(has_50 & ~has_90, "pod_a90_m", lambda _: "required with pod_a50_m")
    problems.check(has_90 & ~has_50, "pod_a50_m", lambda _: "required with pod_a90_m")
    with np.errstate(invalid="ignore"):
        problems.check(
            has_50 & has_90 & ~(a90 > a50),
            "pod_a90_m",
            lambda i: f"must be > pod_a50_m ({_show(a50[i])}), got {_show(a90[i])}",
        )
    problems.check(
        detected & (has_t | has_50 | has_90),
        "detected",
        lambda _: "must be false where a detection threshold or PoD curve is given",
    )
    repaired = _flags(problems, df, "repaired", False)
    after = _optional_numbers(problems, df, "crack_after_repair_m")
    has_after = ~np.isnan(after)
    problems.check(
        repaired & ~has_after, "crack_after_repair_m", lambda _: "required where repaired"
    )
    problems.check(
        ~repaired & has_after,
        "crack_after_repair_m",
        lambda _: "must be blank unless repaired is true",
    )
    return {
        "crack_length_m": crack,
        "detected": detected,
        "detection_threshold_m": threshold,
        "pod_a50_m": a50,
        "pod_a90_m": a90,
        "repaired": repaired,
        "crack_after_repair_m": after,
    }


def load_flights(path: str | Path) -> pd.DataFrame:
    """read_table + validate_flights, errors named after the file."""
    return validate_flights(read_table(path), Path(path).name)


def load_inspections(path: str | Path, known_tails: Iterable[str] | None = None) -> pd.DataFrame:
    """read_table + validate_inspections, errors named after the file."""
    return validate_inspections(read_table(path), Path(path).name, known_tails)


@dataclass(frozen=True)
class TrainingData:
    """Validated records as model inputs.

    tails: aircraft index -> tail (sorted).  loads: stress ranges (aircraft, flights) float64,
    each tail's flights in flown_at order.  observations: one per inspection, `flights` = number
    of the tail's flights flown strictly before inspected_at.  flights: the ordered flights table
    (tail, flight_id, flown_at, stress_range_mpa, mission) plus `aircraft` (index into tails) and
    `flight` (1-based position: the crack after it is trajectory[aircraft, flight]).
    """

    tails: list[str]
    loads: LoadHistory
    observations: Observations
    flights: pd.DataFrame


def _time_ns(series: pd.Series) -> np.ndarray:
    return (
        series.dt.tz_convert("UTC").dt.tz_localize(None).dt.as_unit("ns").to_numpy().view("int64")
    )


def _censoring(inspections: pd.DataFrame) -> tuple[Tensor | None, Tensor | None, Tensor | None]:
    """Observations' (detected, detection_a50_m, detection_a90_m) from validated inspections:
    None, None, None when every row is a measurement; a hard threshold is a50 = a90."""
    if "detected" not in inspections.columns or bool(inspections["detected"].all()):
        return None, None, None
    threshold = inspections["detection_threshold_m"].to_numpy(dtype=np.float64)
    hard = ~np.isnan(threshold)
    a50 = np.where(hard, threshold, inspections["pod_a50_m"].to_numpy(dtype=np.float64))
    a90 = np.where(hard, threshold, inspections["pod_a90_m"].to_numpy(dtype=np.float64))
    detected = inspections["detected"].to_numpy(dtype=bool)
    # measured rows carry no curve: any positive placeholder (read only where not detected)
    a50, a90 = np.where(detected, 1.0, a50), np.where(detected, 1.0, a90)
    return (
        torch.from_numpy(detected.copy()),
        torch.from_numpy(a50.copy()),
        torch.from_numpy(a90.copy()),
    )


def assemble(
    flights: pd.DataFrame, inspections: pd.DataFrame | None = None, source: str = "inspections"
) -> TrainingData:
    """Map validated flights and inspections (from validate_*) to a LoadHistory and Observations.

    Vectorised: flights are ordered by a lexsort on (tail, flown_at, flight_id); each
    inspection's flight count comes from one merged sort of flight and inspection times, an
    inspection sorting before a flight at the same instant (strictly before).  Raises RecordError
    (named `source`, column tail) for an inspection of a tail with no flights.
    """
    tail_code, tails = pd.factorize(flights["tail"], sort=True)
    flown_ns = _time_ns(flights["flown_at"])
    order = np.lexsort((flown_ns, tail_code))
    tied = (np.diff(tail_code[order]) == 0) & (np.diff(flown_ns[order]) == 0)
    if tied.any():  # rare: sort by id as well (hashing every id is the slow part)
        id_code = pd.factorize(flights["flight_id"], sort=True)[0]
        order = np.lexsort((id_code, flown_ns, tail_code))
    tail_sorted = tail_code[order].astype(np.int64)
    counts = np.bincount(tail_sorted, minlength=len(tails))
    starts = np.concatenate(([0], np.cumsum(counts)[:-1])).astype(np.int64)
    position = np.arange(len(order), dtype=np.int64) - starts[tail_sorted]
    stress = np.zeros((len(tails), int(counts.max()) if len(tails) else 0), dtype=np.float64)
    stress[tail_sorted, position] = flights["stress_range_mpa"].to_numpy(dtype=np.float64)[order]
    loads = LoadHistory(torch.from_numpy(stress), torch.from_numpy(counts.astype(np.int64)))

    ordered = flights.iloc[order].copy()
    ordered["aircraft"] = tail_sorted
    ordered["flight"] = position + 1

    if inspections is None or inspections.empty:
        empty = torch.zeros(0, dtype=torch.long)
        observations = Observations(empty, empty.clone(), torch.zeros(0, dtype=torch.float64))
        return TrainingData(list(map(str, tails)), loads, observations, ordered)

    aircraft = pd.Index(tails).get_indexer(inspections["tail"])
    if (aircraft < 0).any():
        i = int(np.argmax(aircraft < 0))
        tail = inspections["tail"].iloc[i]
        raise RecordError(
            source, int(inspections.index[i]), "tail", f"unknown tail {tail!r} (no flights)"
        )
    # One merged sort per (tail, time, kind): kind 0 (inspection) before 1 (flight) at a tie.
    n_flights, n_insp = len(order), len(aircraft)
    event_tail = np.concatenate((tail_sorted, aircraft.astype(np.int64)))
    event_time = np.concatenate((flown_ns[order], _time_ns(inspections["inspected_at"])))
    event_kind = np.concatenate((np.ones(n_flights, np.int8), np.zeros(n_insp, np.int8)))
    merged = np.lexsort((event_kind, event_time, event_tail))
    flights_so_far = np.cumsum(event_kind[merged].astype(np.int64))
    is_insp = merged >= n_flights
    before = np.empty(n_insp, dtype=np.int64)
    insp_tail = event_tail[merged[is_insp]]
    # cumsum counts flights of earlier tails too; subtract the flights of tails sorted before.
    before[merged[is_insp] - n_flights] = flights_so_far[is_insp] - starts[insp_tail]
    observations = Observations(
        torch.from_numpy(aircraft.astype(np.int64)),
        torch.from_numpy(before),
        torch.from_numpy(inspections["crack_length_m"].to_numpy(dtype=np.float64).copy()),
        *_censoring(inspections),
    )
    return TrainingData(list(map(str, tails)), loads, observations, ordered)
