"""Flight and inspection ingestion: validate with model.records, skip exact re-sends, store at once.

One request is one transaction: any invalid row (RecordError) or any key stored with other values
(ConflictError) leaves nothing of the request behind.  Flights go in through the driver's
executemany in large chunks; existing keys are loaded once per request for the touched tails.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import IO, Any

import numpy as np
import pandas as pd
from sqlalchemy import Connection, String, Table, delete, exists, insert, select, type_coerce
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.errors import ConflictError, NotFoundError
from app.services.records import frame_of
from app.tables import Aircraft, Flight, Forecast, Inspection
from model.records import (
    INSPECTION_OPTIONAL_COLUMNS,
    RecordError,
    read_table,
    validate_flights,
    validate_inspections,
)

_CHUNK_ROWS = 100_000
_TIME_COLUMNS = ("flown_at", "inspected_at")
_IN_LIST = 500  # ids per IN (...) list, well below every backend's bound-parameter limit


@dataclass(frozen=True)
class IngestResult:
    inserted: int
    duplicates: int
    aircraft_created: int


def upload_name(filename: str | None) -> str:
    """The client's file name without any directory part, to label errors."""
    return Path(filename or "").name or "upload"


def read_upload(filename: str | None, upload: IO[bytes]) -> pd.DataFrame:
    """Read an uploaded CSV or Parquet file with the offline CLI's reader (model.records).

    The type comes from the file name's suffix, else from the content (Parquet's magic bytes).
    Raises RecordError named after the uploaded file.
    """
    name = upload_name(filename)
    suffix = Path(name).suffix.lower()
    if suffix not in (".csv", ".parquet"):
        head = upload.read(4)
        upload.seek(0)
        suffix = ".parquet" if head == b"PAR1" else ".csv"
    with tempfile.TemporaryDirectory(prefix="fleetpinn-upload-") as folder:
        # A fixed local name: the client's file name only labels errors.
        path = Path(folder) / f"upload{suffix}"
        with path.open("wb") as out:
            shutil.copyfileobj(upload, out, length=1 << 20)
        try:
            return read_table(path)
        except RecordError as exc:
            raise RecordError(name, exc.row, exc.column, exc.reason) from exc


def flights_frame(tail: str, flights: Sequence[dict[str, Any]]) -> pd.DataFrame:
    """A flights frame for one tail from JSON records (flight_id, flown_at, stress_range_mpa, ...)."""
    return pd.DataFrame(
        {
            "tail": [tail] * len(flights),
            "flight_id": [f["flight_id"] for f in flights],
            "flown_at": pd.to_datetime([_utc(f["flown_at"]) for f in flights], utc=True),
            "stress_range_mpa": np.array([f["stress_range_mpa"] for f in flights], dtype=float),
            "mission": [f.get("mission") for f in flights],
        }
    )


def inspections_frame(tail: str, inspections: Sequence[dict[str, Any]]) -> pd.DataFrame:
    """An inspections frame for one tail from JSON records, with every optional column."""
    frame = pd.DataFrame(
        {
            "tail": [tail] * len(inspections),
            "inspection_id": [i["inspection_id"] for i in inspections],
            "inspected_at": pd.to_datetime(
                [_utc(i["inspected_at"]) for i in inspections], utc=True
            ),
            "crack_length_m": np.array([i.get("crack_length_m") for i in inspections], dtype=float),
        }
    )
    for field in INSPECTION_OPTIONAL_COLUMNS:
        frame[field] = pd.Series([i.get(field) for i in inspections], dtype=object)
    return frame


def _utc(value: datetime) -> datetime:
    return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


def _chunks(values: Sequence[Any], size: int = _IN_LIST) -> Iterable[Sequence[Any]]:
    for start in range(0, len(values), size):
        yield values[start : start + size]


def _aircraft_ids(session: Session, tails: Sequence[str]) -> dict[str, int]:
    found: dict[str, int] = {}
    for part in _chunks(tails):
        rows = session.execute(select(Aircraft.tail, Aircraft.id).where(Aircraft.tail.in_(part)))
        found.update({tail: ident for tail, ident in rows})
    return found


def _resolve_tails(
    session: Session, tails: Sequence[str], *, create: bool
) -> tuple[dict[str, int], int]:
    ids = _aircraft_ids(session, tails)
    missing = [t for t in tails if t not in ids]
    if missing and not create:
        raise NotFoundError(f"unknown tail {missing[0]!r}")
    if missing:
        now = datetime.now(UTC)
        session.execute(insert(Aircraft), [{"tail": t, "created_at": now} for t in missing])
        ids.update(_aircraft_ids(session, missing))
    return ids, len(missing)


def _with_stored(
    session: Session, aircraft_ids: Sequence[int], model: type[Flight] | type[Inspection]
) -> list[int]:
    """The aircraft among aircraft_ids that already have rows in model's table."""
    stored: list[int] = []
    for part in _chunks(list(aircraft_ids)):
        query = select(Aircraft.id).where(
            Aircraft.id.in_(part), exists().where(model.aircraft_id == Aircraft.id)
        )
        stored.extend(session.scalars(query))
    return stored


def _db_times(times: pd.Series, dialect: str) -> list[Any]:
    """Timestamps as the driver stores them: SQLAlchemy's SQLite text format, else datetimes."""
    if times.empty:
        return []
    if dialect != "sqlite":
        return list(times.dt.to_pydatetime())
    text = np.datetime_as_string(times.dt.tz_convert(None).to_numpy("datetime64[us]"), unit="us")
    # 'YYYY-MM-DDTHH:MM:SS.ffffff' -> the space-separated form SQLAlchemy writes, in place.
    text.view(np.uint32).reshape(len(text), -1)[:, 10] = ord(" ")
    return text.tolist()


def _executemany(connection: Connection, table: Table, columns: dict[str, list[Any]]) -> None:
    """Insert column lists through the driver's executemany (no per-row ORM or Core work)."""
    compiled = insert(table).compile(dialect=connection.dialect, column_keys=list(columns))
    n = len(next(iter(columns.values())))
    if n == 0:
        return
    for start in range(0, n, _CHUNK_ROWS):
        part = {k: v[start : start + _CHUNK_ROWS] for k, v in columns.items()}
        if compiled.positional:
            keys = compiled.positiontup or []
            rows: list[Any] = list(zip(*(part[k] for k in keys), strict=True))
        else:
            rows = [
                dict(zip(part, values, strict=True)) for values in zip(*part.values(), strict=True)
            ]
        connection.exec_driver_sql(str(compiled), rows)


def _stored_frame(
    session: Session,
    model: type[Flight] | type[Inspection],
    aircraft_ids: Sequence[int],
    columns: Sequence[str],
) -> pd.DataFrame:
    parts = []
    for part in _chunks(list(aircraft_ids)):
        # Times come back in the driver's form (SQLite: text) and are parsed once, vectorised.
        selected = [
            type_coerce(getattr(model, c), String) if c in _TIME_COLUMNS else getattr(model, c)
            for c in columns
        ]
        query = select(*selected).where(model.aircraft_id.in_(part))
        parts.append(frame_of(session.connection(), query, columns))
    return pd.concat(parts, ignore_index=True)


def _split_duplicates(
    new: pd.DataFrame, stored: pd.DataFrame, id_column: str, value_columns: Sequence[str]
) -> pd.Series:
    """Mask of `new` rows already stored with the same values; raises ConflictError otherwise."""
    merged = new.reset_index().merge(
        stored, on=["aircraft_id", id_column], how="inner", suffixes=("", "_stored")
    )
    if merged.empty:
        return pd.Series(False, index=new.index)
    same = np.ones(len(merged), dtype=bool)
    for column in value_columns:
        a, b = merged[column], merged[f"{column}_stored"]
        same &= ((a == b) | (a.isna() & b.isna())).to_numpy()
    if not same.all():
        bad = merged[~same].sort_values("row").iloc[0]
        differs = [c for c in value_columns if not _equal(bad[c], bad[f"{c}_stored"])]
        raise ConflictError(
            f"row {int(bad['row'])}: {id_column} {bad[id_column]!r} of tail {bad['tail']!r} "
            f"is already stored with other values ({', '.join(differs)} differ)"
        )
    return pd.Series(new.index.isin(merged["row"]), index=new.index)


def _equal(a: Any, b: Any) -> bool:
    return bool((pd.isna(a) and pd.isna(b)) or a == b)


def ingest_flights(
    session: Session, records: pd.DataFrame, *, source: str, create_tails: bool
) -> IngestResult:
    """Validate and store flights of any number of tails in one transaction.

    An exact re-send of a stored (tail, flight_id) counts as a duplicate; the same key with other
    values raises ConflictError; invalid rows raise RecordError; an unknown tail raises
    NotFoundError unless create_tails.  New flights void the forecasts cached for their tails.
    """
    flights = validate_flights(records, source)
    if flights.empty:
        return IngestResult(0, 0, 0)
    # The database keeps microseconds; compare and store what a re-send will read back.
    flights["flown_at"] = flights["flown_at"].dt.floor("us")
    tails = list(pd.unique(flights["tail"]))
    ids, created = _resolve_tails(session, tails, create=create_tails)
    flights["aircraft_id"] = flights["tail"].map(ids).astype(np.int64)

    duplicate = pd.Series(False, index=flights.index)
    stored_ids = _with_stored(session, list(ids.values()), Flight)
    if stored_ids:
        columns = ["aircraft_id", "flight_id", "flown_at", "stress_range_mpa", "mission"]
        stored = _stored_frame(session, Flight, stored_ids, columns)
        stored["flown_at"] = pd.to_datetime(stored["flown_at"], utc=True, format="ISO8601")
        stored["mission"] = stored["mission"].astype(object)
        duplicate = _split_duplicates(
            flights, stored, "flight_id", ["flown_at", "stress_range_mpa", "mission"]
        )
    new = flights[~duplicate.to_numpy()]
    connection = session.connection()
    try:
        _executemany(
            connection,
            Flight.__table__,  # type: ignore[arg-type]
            {
                "aircraft_id": new["aircraft_id"].tolist(),
                "flight_id": new["flight_id"].tolist(),
                "flown_at": _db_times(new["flown_at"], connection.dialect.name),
                "stress_range_mpa": new["stress_range_mpa"].tolist(),
                "mission": new["mission"].tolist(),
            },
        )
        touched = sorted(set(new["aircraft_id"].tolist()))
        for part in _chunks(touched):
            session.execute(delete(Forecast).where(Forecast.aircraft_id.in_(part)))
        session.commit()
    except IntegrityError as exc:
        session.rollback()
        raise ConflictError(f"flights changed by a concurrent request; retry ({exc.orig})") from exc
    return IngestResult(len(new), int(duplicate.sum()), created)


def ingest_upload(session: Session, filename: str | None, upload: IO[bytes]) -> IngestResult:
    """Read an uploaded flights file of many tails and ingest it, creating unknown tails."""
    frame = read_upload(filename, upload)
    return ingest_flights(session, frame, source=upload_name(filename), create_tails=True)


def ingest_inspections(session: Session, records: pd.DataFrame, *, source: str) -> IngestResult:
    """Validate and store inspections of known tails, with the idempotency rules of flights."""
    inspections = validate_inspections(records, source)
    if inspections.empty:
        return IngestResult(0, 0, 0)
    inspections = _with_optional_columns(inspections)
    inspections["inspected_at"] = inspections["inspected_at"].dt.floor("us")
    tails = list(pd.unique(inspections["tail"]))
    ids, _ = _resolve_tails(session, tails, create=False)
    inspections["aircraft_id"] = inspections["tail"].map(ids).astype(np.int64)
    duplicate = pd.Series(False, index=inspections.index)
    stored_ids = _with_stored(session, list(ids.values()), Inspection)
    values = ["inspected_at", "crack_length_m", *INSPECTION_OPTIONAL_COLUMNS]
    if stored_ids:
        columns = ["aircraft_id", "inspection_id", *values]
        stored = _stored_frame(session, Inspection, stored_ids, columns)
        stored["inspected_at"] = pd.to_datetime(stored["inspected_at"], utc=True, format="ISO8601")
        for flag in ("detected", "repaired"):
            stored[flag] = stored[flag].astype(bool)
        for number in ("crack_length_m", "detection_threshold_m", "pod_a50_m", "pod_a90_m"):
            stored[number] = stored[number].astype("float64")
        stored["crack_after_repair_m"] = stored["crack_after_repair_m"].astype("float64")
        duplicate = _split_duplicates(inspections, stored, "inspection_id", values)
    new = inspections[~duplicate.to_numpy()]
    try:
        session.add_all(
            Inspection(
                aircraft_id=int(record["aircraft_id"]),
                inspection_id=str(record["inspection_id"]),
                inspected_at=inspected_at,
                crack_length_m=_optional(record["crack_length_m"]),
                detected=bool(record["detected"]),
                detection_threshold_m=_optional(record["detection_threshold_m"]),
                pod_a50_m=_optional(record["pod_a50_m"]),
                pod_a90_m=_optional(record["pod_a90_m"]),
                repaired=bool(record["repaired"]),
                crack_after_repair_m=_optional(record["crack_after_repair_m"]),
            )
            for record, inspected_at in zip(
                new.drop(columns="inspected_at").to_dict("records"),
                new["inspected_at"].dt.to_pydatetime(),
                strict=True,
            )
        )
        # A repair restarts the tail's crack: its cached forecasts no longer hold.
        repaired = sorted(set(new.loc[new["repaired"].to_numpy(bool), "aircraft_id"].tolist()))
        for part in _chunks(repaired):
            session.execute(delete(Forecast).where(Forecast.aircraft_id.in_(part)))
        session.commit()
    except IntegrityError as exc:
        session.rollback()
        raise ConflictError(
            f"inspections changed by a concurrent request; retry ({exc.orig})"
        ) from exc
    return IngestResult(len(new), int(duplicate.sum()), 0)


def _with_optional_columns(inspections: pd.DataFrame) -> pd.DataFrame:
    """Validated inspections with every optional column (a file may have none of them)."""
    out = inspections.copy()
    defaults: dict[str, Any] = {"detected": True, "repaired": False}
    for field in INSPECTION_OPTIONAL_COLUMNS:
        if field not in out.columns:
            out[field] = defaults.get(field, np.nan)
    return out


def _optional(value: Any) -> float | None:
    return None if pd.isna(value) else float(value)


def list_inspections(session: Session, aircraft_id: int) -> list[Inspection]:
    query = (
        select(Inspection)
        .where(Inspection.aircraft_id == aircraft_id)
        .order_by(Inspection.inspected_at, Inspection.inspection_id)
    )
    return list(session.scalars(query))
