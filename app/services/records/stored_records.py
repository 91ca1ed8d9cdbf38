"""Stored flights and inspections read back in model.records' validated frame shapes.

RecordKind describes one record table (its key within a tail and the values stored with it), so
the bulk reads here and the ingest (app.services.records.ingest) treat flights and inspections alike.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, cast

import pandas as pd
from sqlalchemy import ClauseElement, ColumnElement, String, exists, select, type_coerce
from sqlalchemy.orm import Session

from app.storage import bulk, chunks, parse_utc
from app.tables import DEFAULT_LOCATION_ID, Aircraft, Flight, Inspection
from model import records


@dataclass(frozen=True)
class RecordKind:
    """One record table: rows are keyed by (aircraft, key); `values` are stored with the key,
    the time first; `flags` are booleans, `text` strings or None, the others floats."""

    noun: str
    table: type[Flight] | type[Inspection]
    key: str
    values: tuple[str, ...]
    flags: tuple[str, ...] = ()
    text: tuple[str, ...] = ()
    # integer columns stored beside the values (not the file contract's) that a re-send must
    # match too, or it is a conflict: an inspection's location
    compared: tuple[str, ...] = ()

    @property
    def time(self) -> str:
        return self.values[0]

    def selected(self, names: Sequence[str]) -> list[Any]:
        """Columns to read in the driver's form (times as text, parsed by typed())."""
        return [
            type_coerce(getattr(self.table, n), String)
            if n == self.time
            else getattr(self.table, n)
            for n in names
        ]

    def typed(self, frame: pd.DataFrame) -> pd.DataFrame:
        """The stored values in validate_*'s dtypes: UTC times, bools, objects, float64."""
        frame[self.time] = parse_utc(frame[self.time])
        for name in self.values[1:]:
            if name in self.flags:
                frame[name] = frame[name].astype(bool)
            elif name in self.text:
                frame[name] = frame[name].astype(object)
            else:
                frame[name] = frame[name].astype("float64")
        return frame


# model.records' columns after tail and key: the time first, then the required, then the optional
FLIGHTS = RecordKind(
    "flights",
    Flight,
    "flight_id",
    (*records.FLIGHT_COLUMNS[2:], *records.FLIGHT_OPTIONAL_COLUMNS),
    text=("mission",),
)
INSPECTIONS = RecordKind(
    "inspections",
    Inspection,
    "inspection_id",
    (*records.INSPECTION_COLUMNS[2:], *records.INSPECTION_OPTIONAL_COLUMNS),
    flags=("detected", "repaired"),
    compared=("location_id",),
)


def _stored(
    session: Session,
    kind: RecordKind,
    aircraft_ids: Sequence[int],
    *,
    ordered: bool,
    where: ColumnElement[bool] | None = None,
) -> pd.DataFrame:
    table = kind.table

    def query_for(ids: list[int]) -> ClauseElement:
        query = (
            select(Aircraft.tail, *kind.selected([kind.key, *kind.values]))
            .join(Aircraft, Aircraft.id == table.aircraft_id)
            .where(table.aircraft_id.in_(ids))
        )
        if where is not None:
            query = query.where(where)
        if not ordered:  # model.training_data.assemble sorts them itself, faster than the database
            return query
        return query.order_by(Aircraft.tail, getattr(table, kind.time), getattr(table, kind.key))

    columns = ["tail", kind.key, *kind.values]
    return kind.typed(bulk(session.connection()).frame_in(list(aircraft_ids), query_for, columns))


def stored_flights(session: Session, aircraft_ids: Sequence[int]) -> pd.DataFrame:
    """Flights of these aircraft: tail, flight_id, flown_at (UTC), stress_range_mpa, mission."""
    return _stored(session, FLIGHTS, aircraft_ids, ordered=False)


def stored_inspections(
    session: Session, aircraft_ids: Sequence[int], location_id: int = DEFAULT_LOCATION_ID
) -> pd.DataFrame:
    """Inspections of these aircraft at the location in validate_inspections' shape with every optional column,
    ordered by tail and time: tail, inspection_id, inspected_at (UTC), crack_length_m (NaN: not
    detected), detected, detection_threshold_m, pod_a50_m, pod_a90_m, repaired,
    crack_after_repair_m."""
    at = Inspection.location_id == location_id
    return _stored(session, INSPECTIONS, aircraft_ids, ordered=True, where=at)


def with_records(session: Session, kind: RecordKind, aircraft_ids: Sequence[int]) -> list[int]:
    """The aircraft among aircraft_ids that have rows of this kind."""
    found: list[int] = []
    for part in chunks(list(aircraft_ids)):
        query = select(Aircraft.id).where(
            Aircraft.id.in_(part), exists().where(kind.table.aircraft_id == Aircraft.id)
        )
        found.extend(session.scalars(query))
    return found


def stored_by_key(session: Session, kind: RecordKind, keys: pd.DataFrame) -> pd.DataFrame:
    """The stored rows with these keys (columns aircraft_id and kind.key): aircraft_id, key and
    the values.  One query per aircraft and chunk of its keys (the unique index answers each)."""
    table, store = kind.table, bulk(session.connection())
    columns = ["aircraft_id", kind.key, *kind.values, *kind.compared]
    parts = []
    values = keys[kind.key].to_numpy(dtype=object)
    for aircraft, rows in keys.groupby("aircraft_id").indices.items():

        def query_for(
            part: list[str], aircraft_id: int = int(cast(int, aircraft))
        ) -> ClauseElement:
            return select(*kind.selected(columns)).where(
                table.aircraft_id == aircraft_id, getattr(table, kind.key).in_(part)
            )

        parts.append(store.frame_in(values[rows].tolist(), query_for, columns))
    frame = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=columns)
    return kind.typed(frame)
