"""The fleet's forecasts as a table for other tools: CSV, Parquet or JSON, in the ranking's order.

One row per tail (per (tail, location) once several locations have models, with a location
column: app.services.ranking.location_ranking), most urgent first (app.services.ranking.order.urgency_key
"risk"), holding what an engineer plans with: the crack after the last flight, its p05/p50/p95 on the as-of date and at
the horizon's end, P(critical by then), the critical-date quantiles, inspect-by and whether it
is overdue, whether the tail is past critical (past_critical, past_critical_since; a crack
length at or past a_crit is missing, never the bound a march holds it at), its data age
(last_flown_at, days_since_last_flight, days_since_last_inspection, stale), the last
inspection and, where some row's location gives a limit stress, the residual strength at the
p50 crack on the as-of date with its criterion and margin over that limit (STRENGTH_COLUMNS:
null on a row whose location gives none, absent where no row's does, as before).  Units in the column names (m, mpa); times are UTC: ISO 8601 with Z in CSV and JSON
(TIMESTAMP_FORMAT), timestamp[us, UTC] in Parquet.  The request's deadline (app.budget) is
checked before the ranking, between its rows and before the frame is typed and encoded: an export
answered 503 stops there instead of encoding every tail for a client that is gone.
"""

from __future__ import annotations

import io
import json
from datetime import date
from typing import Any

import pandas as pd
from sqlalchemy.orm import Session

from app import budget
from app.config import Settings
from app.services.dates import as_of_time
from app.services.forecasts.reports import crack_band
from app.services.forecasts.tail_status import below_critical
from app.services.ranking import location_ranking

FORMATS = ("csv", "parquet", "json")
MEDIA_TYPES = {
    "csv": "text/csv",
    "parquet": "application/vnd.apache.parquet",
    "json": "application/json",
}
TIMESTAMP_FORMAT = "%Y-%m-%dT%H:%M:%SZ"
# Every tail: the JSON ranking caps its page, the export does not.
_ALL = 10**9

TIME_COLUMNS = [
    "as_of",
    "horizon_end",
    "origin",
    "critical_date",
    "critical_date_p05",
    "critical_date_p50",
    "critical_date_p95",
    "inspect_by",
    "last_inspected_at",
    "past_critical_since",
    "last_flown_at",
    "computed_at",
]
COLUMNS = [
    "rank",
    "tail",
    "model_version",
    "as_of",
    "horizon_days",
    "horizon_end",
    "origin",
    "flights_flown",
    "flights_per_day",
    "crack_last_flight_m",
    "crack_as_of_p05_m",
    "crack_as_of_p50_m",
    "crack_as_of_p95_m",
    "crack_at_horizon_p05_m",
    "crack_at_horizon_p50_m",
    "crack_at_horizon_p95_m",
    "critical_crack_m",
    "prob_critical",
    "flights_to_critical",
    "critical_date",
    "critical_date_p05",
    "critical_date_p50",
    "critical_date_p95",
    "inspect_by",
    "overdue",
    "past_critical",
    "past_critical_since",
    "last_flown_at",
    "days_since_last_flight",
    "days_since_last_inspection",
    "stale",
    "last_inspection_id",
    "last_inspected_at",
    "last_inspection_detected",
    "last_inspection_crack_m",
    "last_inspection_repaired",
    "computed_at",
]
# after critical_crack_m, where some row has one (app.services.ranking.ranking_page)
STRENGTH_COLUMNS = [
    "limit_stress_mpa",
    "residual_strength_mpa",
    "residual_strength_criterion",
    "residual_strength_margin",
]


def export_frame(
    session: Session,
    settings: Settings,
    *,
    version: int | None = None,
    horizon_days: int | None = None,
    as_of: date | None = None,
) -> pd.DataFrame:
    """Every tail of `version` (default: active) as one row, in the ranking's order, over
    horizon_days (default forecast_horizon_days, the precomputed one) after as_of (default
    settings.today()).  Times are tz-aware UTC; a value not reached within the horizon is
    missing.  Raises ConflictError (no active model), NotFoundError (unknown version)."""
    horizon = horizon_days or min(settings.forecast_horizon_days, settings.max_horizon_days)
    as_of = as_of or settings.today()
    budget.check()
    version, critical, _, items = location_ranking.ranking(
        session,
        limit=_ALL,
        settings=settings,
        horizon_days=horizon,
        by="risk",
        as_of=as_of,
        version=version,
    )
    start = as_of_time(as_of)
    rows: list[dict[str, Any]] = []
    for rank, item in enumerate(items, start=1):
        budget.check()
        last, age = item.last_inspection, item.data_age
        critical_here = item.critical_crack_m or critical  # a (tail, location) row's own
        now = crack_band(item.risk.crack_as_of, critical_here)
        end = crack_band(item.risk.crack_at_horizon, critical_here)
        strength = item.residual_strength
        rows.append(
            {
                "rank": rank,
                "tail": item.tail,
                "location": item.location,
                "model_version": item.model_version or version,
                "as_of": start,
                "horizon_days": horizon,
                "horizon_end": start + pd.Timedelta(days=horizon),
                "origin": item.origin,
                "flights_flown": item.flights_flown,
                "flights_per_day": item.flights_per_day,
                "crack_last_flight_m": below_critical(item.crack_length_m, critical_here),
                "crack_as_of_p05_m": now.p05,
                "crack_as_of_p50_m": now.p50,
                "crack_as_of_p95_m": now.p95,
                "crack_at_horizon_p05_m": end.p05,
                "crack_at_horizon_p50_m": end.p50,
                "crack_at_horizon_p95_m": end.p95,
                "critical_crack_m": critical_here,
                "limit_stress_mpa": None if strength is None else strength.limit_stress_mpa,
                "residual_strength_mpa": None
                if strength is None
                else strength.residual_strength_mpa,
                "residual_strength_criterion": None if strength is None else strength.criterion,
                "residual_strength_margin": None if strength is None else strength.margin,
                "prob_critical": item.risk.prob_critical,
                "flights_to_critical": item.flights_to_critical,
                "critical_date": item.critical_date,
                "critical_date_p05": item.critical_dates[0],
                "critical_date_p50": item.critical_dates[1],
                "critical_date_p95": item.critical_dates[2],
                "inspect_by": item.inspect_by,
                "overdue": item.overdue,
                "past_critical": item.past.past_critical,
                "past_critical_since": item.past.past_critical_since,
                "last_flown_at": age.last_flown_at,
                "days_since_last_flight": age.days_since_last_flight,
                "days_since_last_inspection": age.days_since_last_inspection,
                "stale": age.stale,
                "last_inspection_id": None if last is None else last.inspection_id,
                "last_inspected_at": None if last is None else last.inspected_at,
                "last_inspection_detected": None if last is None else last.detected,
                "last_inspection_crack_m": None if last is None else last.crack_length_m,
                "last_inspection_repaired": None if last is None else last.repaired,
                "computed_at": item.computed_at,
            }
        )
    budget.check()
    # (tail, location) rows name their location; a one-location fleet's columns are as before
    located = any(item.location is not None for item in items)
    columns = [*COLUMNS[:2], "location", *COLUMNS[2:]] if located else list(COLUMNS)
    if any(item.residual_strength is not None for item in items):
        after = columns.index("critical_crack_m") + 1
        columns[after:after] = STRENGTH_COLUMNS
    frame = pd.DataFrame(rows, columns=columns)
    for column in TIME_COLUMNS:
        frame[column] = pd.to_datetime(frame[column], utc=True).dt.as_unit("us")
    frame["last_inspection_detected"] = frame["last_inspection_detected"].astype("boolean")
    frame["last_inspection_repaired"] = frame["last_inspection_repaired"].astype("boolean")
    if "residual_strength_mpa" in frame:
        numbers = ["limit_stress_mpa", "residual_strength_mpa", "residual_strength_margin"]
        frame[numbers] = frame[numbers].astype("float64")
    return frame.astype(
        {
            "overdue": bool,
            "past_critical": bool,
            "stale": bool,
            "flights_flown": "int64",
            "flights_to_critical": "Int64",
            "days_since_last_flight": "int64",
            "days_since_last_inspection": "Int64",
        }
    )


def _text_times(frame: pd.DataFrame) -> pd.DataFrame:
    """The frame with its times as ISO 8601 UTC text with Z (missing: null)."""
    out = frame.copy()
    for column in TIME_COLUMNS:
        text = out[column].dt.strftime(TIMESTAMP_FORMAT)
        out[column] = text.astype(object).where(out[column].notna(), None)
    return out


def encode(frame: pd.DataFrame, export_format: str) -> bytes:
    """The export in one of FORMATS.  Raises ValueError for another format, DeadlineExceeded
    when the request's time has run out."""
    budget.check()
    if export_format == "csv":
        return _text_times(frame).to_csv(index=False).encode()
    if export_format == "json":
        # json.dumps, not DataFrame.to_json: floats keep every digit (to_json rounds to 10)
        text = _text_times(frame).astype(object)
        records = text.where(text.notna(), None).to_dict(orient="records")
        return json.dumps(records, ensure_ascii=False).encode()
    if export_format == "parquet":
        buffer = io.BytesIO()
        frame.to_parquet(buffer, index=False)
        return buffer.getvalue()
    raise ValueError(f"format must be one of {FORMATS}, got {export_format!r}")


def format_of(path_suffix: str) -> str:
    """The export format a file name's suffix asks for ('.csv' -> 'csv').  Raises ValueError."""
    name = path_suffix.lower().lstrip(".")
    if name not in FORMATS:
        raise ValueError(f"must end in .csv, .parquet or .json, got {path_suffix!r}")
    return name
