"""Plausibility of records beyond the file contract (model.records): physical bounds and clocks.

model.records checks what any record file must satisfy (columns, positive numbers, the
inspection combinations); these checks depend on the service's settings: a crack above
max_crack_length_m (a value in mm sent as m), a stress range (a flight's one, or each of its
cycles') above max_stress_range_mpa, a flight or inspection dated beyond now +
clock_skew_seconds or before earliest_record_date, a repair or initial crack at or beyond the
critical crack.  Each raises model.records.RecordError naming the first bad row and column, so
the HTTP answer is the same 422 as for any invalid row.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, date, datetime, timedelta

import numpy as np
import pandas as pd

from app.config import Settings
from model.records import RecordError


@dataclass(frozen=True)
class Bounds:
    max_crack_length_m: float
    critical_crack_m: float
    max_stress_range_mpa: float
    clock_skew_seconds: float
    earliest_record_date: date

    @classmethod
    def of(cls, settings: Settings) -> Bounds:
        return cls(
            settings.max_crack_length_m,
            settings.critical_crack_m,
            settings.max_stress_range_mpa,
            settings.clock_skew_seconds,
            settings.earliest_record_date,
        )

    def latest(self, now: datetime | None = None) -> pd.Timestamp:
        """The latest time a record may carry."""
        now = now or datetime.now(UTC)
        return pd.Timestamp(now + timedelta(seconds=self.clock_skew_seconds))

    def earliest(self) -> pd.Timestamp:
        """The earliest time a record may carry (00:00 UTC of earliest_record_date)."""
        return pd.Timestamp(self.earliest_record_date, tz="UTC")


class _Problems:
    """The first bad row (ties: the order the checks were made in)."""

    def __init__(self, source: str, frame: pd.DataFrame) -> None:
        self.source, self.frame = source, frame
        self.found: list[tuple[int, int, str, str]] = []

    def check(self, bad: np.ndarray, column: str, reason: str) -> None:
        if bad.any():
            row = int(self.frame.index[int(np.argmax(bad))])
            shown = _shown(self.frame.loc[row, column])
            self.found.append((row, len(self.found), column, f"{reason}, got {shown}"))

    def raise_first(self) -> None:
        if self.found:
            row, _, column, reason = min(self.found)
            raise RecordError(self.source, row, column, reason)


def _shown(value: object) -> str:
    """A bad value as its sender wrote it: 5.0, not numpy's np.float64(5.0)."""
    if isinstance(value, pd.Timestamp):
        return value.isoformat()
    if isinstance(value, np.generic):
        value = value.item()
    return repr(value)


def _values(frame: pd.DataFrame, column: str) -> np.ndarray:
    """float64 (rows,), -inf where blank or absent (never out of bounds)."""
    if column not in frame.columns:
        return np.full(len(frame), -np.inf)
    values = pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=np.float64)
    return np.nan_to_num(values, nan=-np.inf)


def _above(frame: pd.DataFrame, column: str, bound: float) -> np.ndarray:
    return _values(frame, column) > bound


def _future(frame: pd.DataFrame, column: str, bounds: Bounds, now: datetime | None) -> np.ndarray:
    return (frame[column] > bounds.latest(now)).to_numpy()


def _too_early(frame: pd.DataFrame, column: str, bounds: Bounds) -> np.ndarray:
    return (frame[column] < bounds.earliest()).to_numpy()


def _early_reason(bounds: Bounds) -> str:
    return f"lies before {bounds.earliest_record_date} (FLEETPINN_EARLIEST_RECORD_DATE)"


def _range_limit(bounds: Bounds) -> str:
    return f"must be <= {bounds.max_stress_range_mpa:g} MPa (FLEETPINN_MAX_STRESS_RANGE_MPA)"


def first_implausible_cycle(ranges: np.ndarray, bounds: Bounds) -> tuple[int, str] | None:
    """The position of the first of a flight's (or a file's) cycle ranges (cycles,) MPa above
    max_stress_range_mpa and the reason to give for it, None where every one lies within it.
    The bound is a cycle's: a flight's damage-equivalent range sums all its cycles' damage
    (1,000 cycles of 200 MPa are 2,000 MPa under Paris, m = 3) and is not bounded by it."""
    above = np.flatnonzero(np.asarray(ranges, dtype=np.float64) > bounds.max_stress_range_mpa)
    if not len(above):
        return None
    at = int(above[0])
    return at, f"a cycle's stress range {_range_limit(bounds)}, got {_shown(ranges[at])}"


def check_flights(
    flights: pd.DataFrame,
    source: str,
    bounds: Bounds,
    now: datetime | None = None,
    *,
    cycled: np.ndarray | None = None,
) -> None:
    """Validated flights (model.records.validate_flights); raises RecordError.  cycled: bool
    (rows,), True where a flight's stress_range_mpa is its cycles' damage-equivalent range,
    whose cycles were bounded one by one where they were read (first_implausible_cycle, by
    app.services.records.spectra); the bound applies to the other flights' one range."""
    problems = _Problems(source, flights)
    one_range = np.ones(len(flights), dtype=bool) if cycled is None else ~cycled
    problems.check(
        _above(flights, "stress_range_mpa", bounds.max_stress_range_mpa) & one_range,
        "stress_range_mpa",
        _range_limit(bounds),
    )
    problems.check(
        _future(flights, "flown_at", bounds, now),
        "flown_at",
        f"lies in the future (more than {bounds.clock_skew_seconds:g} s after now)",
    )
    problems.check(_too_early(flights, "flown_at", bounds), "flown_at", _early_reason(bounds))
    problems.raise_first()


def check_inspections(
    inspections: pd.DataFrame, source: str, bounds: Bounds, now: datetime | None = None
) -> None:
    """Validated inspections (model.records.validate_inspections); raises RecordError."""
    problems = _Problems(source, inspections)
    limit = f"must be <= {bounds.max_crack_length_m:g} m (FLEETPINN_MAX_CRACK_LENGTH_M)"
    for column in ("crack_length_m", "detection_threshold_m", "pod_a50_m", "pod_a90_m"):
        problems.check(_above(inspections, column, bounds.max_crack_length_m), column, limit)
    problems.check(
        _values(inspections, "crack_after_repair_m") >= bounds.critical_crack_m,
        "crack_after_repair_m",
        f"must be < the critical crack ({bounds.critical_crack_m:g} m): a repair leaves a "
        "smaller crack",
    )
    problems.check(
        _future(inspections, "inspected_at", bounds, now),
        "inspected_at",
        f"lies in the future (more than {bounds.clock_skew_seconds:g} s after now)",
    )
    problems.check(
        _too_early(inspections, "inspected_at", bounds), "inspected_at", _early_reason(bounds)
    )
    problems.raise_first()


def check_initial_crack(initial_crack_m: float | None, bounds: Bounds, source: str) -> None:
    """A tail's initial crack must lie below the critical crack; raises RecordError."""
    if initial_crack_m is not None and initial_crack_m >= bounds.critical_crack_m:
        raise RecordError(
            source,
            None,
            "initial_crack_m",
            f"must be < the critical crack ({bounds.critical_crack_m:g} m), got "
            f"{_shown(initial_crack_m)}",
        )
