"""Flight and inspection ingestion: validate, skip exact re-sends, store at once.

Validation is the offline CLI's (model.record_validation).  Flights and inspections share one
algorithm (_store, driven by app.services.records.stored_records.RecordKind).  One request is one transaction:
any invalid or implausible row (RecordError; the bounds of app.services.records.plausibility) or any key
stored with other values (ConflictError) leaves nothing of the request behind.  What is stored
points at the request's audit event (who stored it); new inspections carry their comparison
with the tail's forecast (app.services.forecasts.assessment).  Rows go in through the driver's
executemany in large chunks, or one COPY on PostgreSQL (app.storage); re-sends are found by
looking up the incoming keys only, on tails that already have rows.  The tables' triggers check
that stored flights refer to existing aircraft and audit events once per statement (migration
9c4d2e7f1a30): an aircraft deleted meanwhile fails the insert as a concurrent change.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from typing import IO, Any

import numpy as np
import pandas as pd
from sqlalchemy import insert, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app import budget, metrics
from app.config import Settings
from app.errors import ConflictError, NotFoundError
from app.services import audit
from app.services.forecasts import assessment, forecast_cache
from app.services.forecasts.assessment import Assessment
from app.services.records import aircraft_locations, locations, plausibility, spectra
from app.services.records.stored_records import (
    FLIGHTS,
    INSPECTIONS,
    RecordKind,
    stored_by_key,
    with_records,
)
from app.services.records.uploads import read_upload, upload_name
from app.storage import bulk, chunks
from app.tables import Aircraft, Inspection
from model.record_validation import validate_flights, validate_inspections
from model.records import INSPECTION_OPTIONAL_COLUMNS, RecordError

_TAILS_NAMED = 20  # an ingest's audit event names at most this many of its tails
# Tries of one ingest whose keys concurrent requests keep storing first (each retry finds more
# of them stored, so a second try normally answers).
_ATTEMPTS = 3


@dataclass(frozen=True)
class IngestResult:
    inserted: int
    duplicates: int
    aircraft_created: int
    # New inspections compared with their tails' forecasts (empty for flights).
    assessments: tuple[Assessment, ...] = ()


def check_batch_size(rows: int, limit: int) -> None:
    """Raises RecordError when a JSON batch holds more than `limit` rows (max_batch_rows)."""
    if rows > limit:
        raise RecordError(
            "body",
            None,
            None,
            f"{rows} rows in one request, at most {limit} (max_batch_rows); "
            "send more as a file to POST /flights/upload",
        )


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
    frame["location"] = pd.Series([i.get("location") for i in inspections], dtype=object)
    return frame


def _utc(value: datetime) -> datetime:
    return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


def _aircraft_ids(session: Session, tails: Sequence[str]) -> dict[str, int]:
    found: dict[str, int] = {}
    for part in chunks(tails):
        rows = session.execute(select(Aircraft.tail, Aircraft.id).where(Aircraft.tail.in_(part)))
        found.update({tail: ident for tail, ident in rows})
    return found


def _resolve_tails(
    session: Session, tails: Sequence[str], *, create: bool
) -> tuple[dict[str, int], list[str]]:
    """Ids of these tails and the tails created for this request; raises NotFoundError for an
    unknown tail unless `create`."""
    ids = _aircraft_ids(session, tails)
    missing = [t for t in tails if t not in ids]
    if missing and not create:
        raise NotFoundError(f"unknown tail {missing[0]!r}")
    if missing:
        now = datetime.now(UTC)
        session.execute(insert(Aircraft), [{"tail": t, "created_at": now} for t in missing])
        ids.update(_aircraft_ids(session, missing))
    return ids, missing


def _duplicates(new: pd.DataFrame, stored: pd.DataFrame, kind: RecordKind) -> np.ndarray:
    """Mask of `new` rows stored with the same values; raises ConflictError for a key stored
    with other values."""
    merged = new.reset_index().merge(
        stored, on=["aircraft_id", kind.key], how="inner", suffixes=("", "_stored")
    )
    if merged.empty:
        return np.zeros(len(new), dtype=bool)
    same = np.ones(len(merged), dtype=bool)
    columns = [*kind.values, *(c for c in kind.compared if c in new.columns)]
    for column in columns:
        a, b = merged[column], merged[f"{column}_stored"]
        same &= ((a == b) | (a.isna() & b.isna())).to_numpy()
    if not same.all():
        bad = merged[~same].sort_values("row").iloc[0]
        differs = [c for c in columns if not _equal(bad[c], bad[f"{c}_stored"])]
        raise ConflictError(
            f"row {int(bad['row'])}: {kind.key} {bad[kind.key]!r} of tail {bad['tail']!r} "
            f"is already stored with other values ({', '.join(differs)} differ)"
        )
    return np.asarray(new.index.isin(merged["row"]))


def _equal(a: Any, b: Any) -> bool:
    return bool((pd.isna(a) and pd.isna(b)) or a == b)


def _store(
    session: Session,
    kind: RecordKind,
    records: pd.DataFrame,
    *,
    create_tails: bool,
    actor: audit.Actor,
    source: str,
    settings: Settings,
    extra: pd.DataFrame | None = None,
    after_insert: Callable[[Session, pd.DataFrame], None] | None = None,
    with_ids: bool = False,
) -> tuple[IngestResult, pd.DataFrame]:
    """The one ingest of validated records (kind.values complete) in one transaction: resolve
    tails, skip exact re-sends (looked up by the incoming keys only), record the audit event,
    insert the rest through the driver (with `extra` columns, indexed like records), and tell the
    forecast cache in the same transaction (new flights advance its tails' rows, an inspection
    drops them: it moves its tail's own growth posterior, model.tracking).  Returns the result
    and the rows stored.

    A unique key that another request stored meanwhile (the same new tail, or the same rows
    re-sent at once) fails the insert; the request then runs again from a fresh snapshot, where
    those rows are found as duplicates (or as a conflict, when their values differ)."""
    for attempt in range(1, _ATTEMPTS + 1):
        try:
            return _store_once(
                session,
                kind,
                records,
                create_tails=create_tails,
                actor=actor,
                source=source,
                settings=settings,
                extra=extra,
                after_insert=after_insert,
                with_ids=with_ids,
            )
        except IntegrityError as exc:
            session.rollback()
            if attempt == _ATTEMPTS:
                raise ConflictError(
                    f"{kind.noun} changed by concurrent requests {_ATTEMPTS} times in a row; "
                    f"nothing was stored ({exc.orig})"
                ) from exc
    raise AssertionError("unreachable")


def _store_once(
    session: Session,
    kind: RecordKind,
    records: pd.DataFrame,
    *,
    create_tails: bool,
    actor: audit.Actor,
    source: str,
    settings: Settings,
    extra: pd.DataFrame | None,
    after_insert: Callable[[Session, pd.DataFrame], None] | None = None,
    with_ids: bool = False,
) -> tuple[IngestResult, pd.DataFrame]:
    """_store's one try; raises IntegrityError where a concurrent request stored a key first.
    after_insert(session, new rows) writes what goes with the new rows, before the commit;
    with_ids: the new rows get their ids before the insert (column `id` of the rows it hears),
    so what refers to them needs no read-back (a cycle file's flight_spectra)."""
    if records.empty:
        return IngestResult(0, 0, 0), records
    # The database keeps microseconds; compare and store what a re-send will read back.
    records[kind.time] = records[kind.time].dt.floor("us")
    # Codes per row, not a per-row mapping of tail strings (that took 1.3 s of 2.19 M flights).
    codes, uniques = pd.factorize(records["tail"])
    ids, created = _resolve_tails(session, list(uniques), create=create_tails)
    records["aircraft_id"] = np.array([ids[t] for t in uniques], dtype=np.int64)[codes]
    fresh = {ids[t] for t in created}
    maybe_stored = with_records(session, kind, sorted(set(ids.values()) - fresh))
    keys = records.loc[records["aircraft_id"].isin(maybe_stored), ["aircraft_id", kind.key]]
    duplicate = _duplicates(records, stored_by_key(session, kind, keys), kind)
    new = records[~duplicate]
    store = bulk(session.connection())
    # Times go straight to the driver's form: a detour through per-row Timestamp objects cost
    # 8 s of a 2.19 M-flight upload.
    columns = {
        name: store.times(new[name]) if name == kind.time else store.values(new[name])
        for name in ("aircraft_id", kind.key, *kind.values)
    }
    if extra is not None:
        columns.update({name: store.values(extra.loc[new.index, name]) for name in extra.columns})
    if len(new) or created:
        tails = list(pd.unique(new["tail"]))
        event = audit.record(
            session,
            actor,
            f"{kind.noun}.ingest",
            tails[0] if len(tails) == 1 else f"{len(tails)} tails",
            {
                "source": source,
                "inserted": len(new),
                "duplicates": int(duplicate.sum()),
                "aircraft_created": created,
                "tails": tails[:_TAILS_NAMED],
            },
        )
        columns["audit_id"] = store.values(pd.Series(event, index=new.index))
    if with_ids and len(new):  # after the audit event's write: the ids are this one's alone
        given = store.next_ids(kind.table.__table__, len(new))  # type: ignore[arg-type]
        columns["id"] = store.values(pd.Series(given, index=new.index))
        new = new.assign(id=given)
    store.insert(kind.table.__table__, columns)  # type: ignore[arg-type]
    if after_insert is not None:
        after_insert(session, new)
    forecast_cache.recorded(session, kind.noun, new, kind.time, settings)
    budget.check()  # a write out of its time (an upload's) stops here with nothing stored
    session.commit()
    metrics.INGEST_ROWS.labels(kind.noun, "inserted").inc(len(new))
    metrics.INGEST_ROWS.labels(kind.noun, "duplicate").inc(int(duplicate.sum()))
    return IngestResult(len(new), int(duplicate.sum()), len(created)), new


def ingest_flights(
    session: Session,
    records: pd.DataFrame,
    *,
    source: str,
    create_tails: bool,
    actor: audit.Actor,
    settings: Settings,
    recorded: spectra.RecordedLoads | None = None,
) -> IngestResult:
    """Validate and store flights of any number of tails in one transaction, for `actor`.
    recorded: what flights sent as cycles or stress histories recorded, row for row of `records`
    (app.services.records.spectra), stored with the new flights.

    An exact re-send of a stored (tail, flight_id) counts as a duplicate; the same key with other
    values raises ConflictError; invalid or implausible rows raise RecordError; an unknown tail
    raises NotFoundError unless create_tails.  The forecasts cached for their tails advance
    over them in the same transaction (app.services.forecasts.forecast_cache.recorded).
    """
    flights = validate_flights(records, source)
    cycled = None if recorded is None else recorded.cycled(flights.index.to_numpy())
    plausibility.check_flights(flights, source, plausibility.Bounds.of(settings), cycled=cycled)
    result, _ = _store(
        session,
        FLIGHTS,
        flights,
        create_tails=create_tails,
        actor=actor,
        source=source,
        settings=settings,
        after_insert=None if recorded is None else lambda s, new: spectra.store(s, new, recorded),
        with_ids=recorded is not None,
    )
    return result


def ingest_upload(
    session: Session,
    filename: str | None,
    upload: IO[bytes],
    *,
    actor: audit.Actor,
    settings: Settings,
) -> IngestResult:
    """Read an uploaded flights file of many tails and ingest it, creating unknown tails.  A
    cycle file (one row per cycle, model.spectrum_files) is stored with its cycles.  Under a
    deadline (app.budget) it checks it after the parse, the cycles and before the commit:
    raises DeadlineExceeded with nothing stored."""
    frame = read_upload(
        filename,
        upload,
        max_rows=settings.max_upload_rows,
        max_bytes=settings.max_upload_bytes,
    )
    budget.check()
    recorded = None
    if spectra.is_cycle_file(frame):
        frame, recorded = spectra.from_cycle_file(frame, upload_name(filename), settings)
        budget.check()
    return ingest_flights(
        session,
        frame,
        source=upload_name(filename),
        create_tails=True,
        actor=actor,
        settings=settings,
        recorded=recorded,
    )


def ingest_inspections(
    session: Session,
    records: pd.DataFrame,
    *,
    source: str,
    actor: audit.Actor,
    settings: Settings,
) -> IngestResult:
    """Validate and store inspections of known tails, with the idempotency rules of flights.

    Each is first compared with its tail's forecast under the active version
    (app.services.forecasts.assessment): one that disagrees strongly is stored but flagged.  Every new
    inspection voids its tail's cached forecasts: the next forecast conditions on it (its growth
    posterior, model.tracking; a repair also restarts the crack).
    """
    named = (
        records["location"] if "location" in records.columns else pd.Series([None] * len(records))
    )
    location_ids = locations.resolve(session, named, source)  # positional: row k + 1
    aircraft_locations.check_carried(session, records["tail"], location_ids, source)
    records = locations.with_method_pod(session, records, location_ids)
    inspections = _with_optional_columns(validate_inspections(records, source))
    inspections["location_id"] = location_ids[inspections.index.to_numpy() - 1]
    plausibility.check_inspections(inspections, source, plausibility.Bounds.of(settings))
    assessed = assessment.assess(session, inspections, settings)
    assessed["location_id"] = inspections["location_id"]
    session.rollback()  # the comparison may have read (and cached); the write starts afresh
    result, new = _store(
        session,
        INSPECTIONS,
        inspections,
        create_tails=False,
        actor=actor,
        source=source,
        settings=settings,
        extra=assessed,
    )
    flagged = int(assessed.loc[new.index, "flagged"].sum())
    if flagged:
        metrics.INSPECTIONS_FLAGGED.inc(flagged)
    return replace(result, assessments=tuple(assessment.rows_of(new, assessed)))


def _with_optional_columns(inspections: pd.DataFrame) -> pd.DataFrame:
    """Validated inspections with every optional column (a file may have none of them)."""
    out = inspections.copy()
    defaults: dict[str, Any] = {"detected": True, "repaired": False}
    for field in INSPECTION_OPTIONAL_COLUMNS:
        if field not in out.columns:
            out[field] = defaults.get(field, np.nan)
    return out


def list_inspections(session: Session, aircraft_id: int) -> list[Inspection]:
    query = (
        select(Inspection)
        .where(Inspection.aircraft_id == aircraft_id)
        .order_by(Inspection.inspected_at, Inspection.inspection_id)
    )
    return list(session.scalars(query))
