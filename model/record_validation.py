"""Validation of flight and inspection frames against the record contract (model/records.py).

Vectorised pandas, shared by the offline command line and the HTTP upload: every check runs
over whole columns at once, and the first bad row (ties: column order) is raised as one
RecordError naming file, row and column, the one line a user needs to fix the file.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from model.records import (
    FLIGHT_COLUMNS,
    FLIGHT_OPTIONAL_COLUMNS,
    INSPECTION_COLUMNS,
    INSPECTION_OPTIONAL_COLUMNS,
    RecordError,
    read_table,
)

_TRUE = frozenset({"true", "1", "yes", "t", "y"})
_FALSE = frozenset({"false", "0", "no", "f", "n"})
_FIRST_NS = pd.Timestamp("1678-01-01", tz="UTC")
_LAST_NS = pd.Timestamp("2262-01-01", tz="UTC")


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


# An error quotes at most this much of a value (a 60 kB cell came back whole).
_MAX_SHOWN_CHARS = 200


def _show(value: object) -> str:
    if isinstance(value, float | np.floating):
        return f"{float(value):g}"
    text = repr(value)
    if len(text) <= _MAX_SHOWN_CHARS:
        return text
    return f"{text[:_MAX_SHOWN_CHARS]}… ({len(text)} characters)"


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
        problems.check(not_number, column, lambda i: f"must be a number, got {_show(text.iloc[i])}")
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
            unparsed, column, lambda i: f"must be an ISO 8601 time, got {_show(text.iloc[i])}"
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
    """Check and normalise a flights frame (the contract: model/records.py).

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
    """Check and normalise an inspections frame (the contract: model/records.py).

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
    problems.check(~known, column, lambda i: f"must be true or false, got {_show(series.iloc[i])}")
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
