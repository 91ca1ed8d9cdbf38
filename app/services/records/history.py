"""A batch of tails' recorded history, loaded once for training (retrain) and forecasting.

Flights and inspections come back through app.services.records.stored_records; each tail's history is split at
its repairs (app.services.records.segments), its first segment starting at the tail's initial crack, or
the law's a0 where none is set.

A retrain runs one job per location, and every job reads the same aircraft's flights (stored
once per flight, scaled per location): 4.7 s of each job at 300 tails x 7,300 flights.  So a
retrain keeps the flights it read (`keep_flights`) for the next job of the same process, which
reuses them while the flights' generation it read them under is still the stored one
(`flights_generation`); the worker forgets them when its queue runs empty (`forget_flights`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime

import pandas as pd
import torch
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.services.memo import StampedMemo
from app.services.records.locations import local_stress, location_by_id
from app.services.records.segments import Segments, split_at_repairs
from app.services.records.stored_records import stored_flights, stored_inspections
from app.storage import chunks
from app.tables import DEFAULT_LOCATION_ID, Aircraft, AuditEvent
from model.training_data import TrainingData, assemble

# (database, aircraft ids) -> the recorded flights (stored_flights' frame) of the last
# keep_flights read, under the flights' generation it was read at: one entry (2.19 M flights
# take ~220 MB).
_KEPT_FLIGHTS: StampedMemo[pd.DataFrame] = StampedMemo(1)


@dataclass(frozen=True)
class History:
    """Tails with flights among the requested ones, in data.tails order.

    data: flights and inspections (observations) per tail; inspections: the frame the
    observations were assembled from; aircraft_ids: (tails,) their ids; segments: the histories
    split at repairs (segments.last: each tail's current segment).
    """

    data: TrainingData
    inspections: pd.DataFrame
    aircraft_ids: list[int]
    segments: Segments
    # the location whose inspections and local loads these are
    location_id: int = DEFAULT_LOCATION_ID

    def last_repair_ns(self) -> dict[str, int]:
        """Each repaired tail's latest repair time, epoch ns: a repair after the last flight
        starts the tail's projection there."""
        inspections = self.inspections
        if inspections.empty or "repaired" not in inspections.columns:
            return {}
        repairs = inspections[inspections["repaired"].astype(bool)]
        times = repairs["inspected_at"].dt.tz_convert("UTC").dt.tz_localize(None)
        latest = times.dt.as_unit("ns").groupby(repairs["tail"]).max()
        return {str(tail): int(at.value) for tail, at in latest.items()}


# Audit actions that write no flights: a retrain's own activation, the next location's job,
# inspections.  Any other action, a new one included, counts as a write of flights (the safe side:
# the flights are read again).
_NOT_FLIGHTS = (
    "retrain",
    "forecast-batch",
    "job.cancel",
    "model.activate",
    "model.promote",
    "key.create",
    "key.revoke",
    "location.create",
    "location.update",
    "inspections.ingest",
    "inspection.correct",
    "inspection.delete",
    "aircraft.create",
    "aircraft.update",
    "aircraft.locations",
)


def flights_generation(session: Session) -> tuple[int, int, datetime | None]:
    """A stamp that every committed write of flights changes: of the audit events that may
    write flights (all but _NOT_FLIGHTS), their count, the latest one's id and its time.

    Every write of flights (an ingest, a correction or deletion, an aircraft's deletion) records
    an audit event in its own transaction, and events are never removed: the count changes with
    every commit, even one whose event id is lower than an id already committed (PostgreSQL
    hands out ids before commits); the latest event's time tells apart two databases at one
    address that hold as many events (a test's, a restored one).
    """
    writes = AuditEvent.action.not_in(_NOT_FLIGHTS)
    count, latest = session.execute(
        select(func.count(), func.max(AuditEvent.id)).where(writes)
    ).one()
    at = (
        None
        if latest is None
        else session.scalar(select(AuditEvent.at).where(AuditEvent.id == latest))
    )
    return int(count), int(latest or 0), at


def recorded_flights(session: Session, aircraft_ids: Sequence[int], *, keep: bool) -> pd.DataFrame:
    """stored_flights of these aircraft; keep: through the process's memo (module docstring),
    read again unless the last kept read was of the same aircraft in the same database under
    the same flights_generation."""
    if not keep:
        return stored_flights(session, aircraft_ids)
    # read before the flights: a write committed between the two makes the next stamp differ
    stamp = flights_generation(session)
    key = (str(session.connection().engine.url), tuple(aircraft_ids))
    flights = _KEPT_FLIGHTS.get(key, stamp)
    if flights is None:
        flights = stored_flights(session, aircraft_ids)
        _KEPT_FLIGHTS.put(key, stamp, flights)
    # a shallow copy: a caller's new or replaced column never reaches the kept frame
    return flights.copy(deep=False)


def forget_flights() -> None:
    """Drop the flights kept by recorded_flights (a worker whose queue ran empty)."""
    _KEPT_FLIGHTS.clear()


def load_history(
    session: Session,
    aircraft_ids: Sequence[int],
    *,
    initial_crack_m: float,
    location_id: int = DEFAULT_LOCATION_ID,
    keep_flights: bool = False,
) -> History | None:
    """The history of these aircraft at one location (those without flights left out): the
    recorded loads scaled to the location (app.services.records.locations.local_stress) and its own
    inspections; None when none has any flights.

    initial_crack_m: the crack a tail without its own initial crack starts from (the law's a0).
    keep_flights: read the recorded flights through recorded_flights' memo (a retrain, whose
    jobs, one per location, read the same aircraft's).
    """
    flights = recorded_flights(session, aircraft_ids, keep=keep_flights)
    if flights.empty:
        return None
    if location_id != DEFAULT_LOCATION_ID:
        flights = local_stress(flights, location_by_id(session, location_id))
    inspections = stored_inspections(session, aircraft_ids, location_id)
    flown = flights["tail"].unique()  # isin over every flight row cost 0.1 s a tail
    inspections = inspections[inspections["tail"].isin(flown)].reset_index(drop=True)
    data = assemble(flights, inspections)
    by_tail: dict[str, tuple[int, float | None]] = {}
    for part in chunks(list(aircraft_ids)):
        rows = session.execute(
            select(Aircraft.tail, Aircraft.id, Aircraft.initial_crack_m).where(
                Aircraft.id.in_(part)
            )
        )
        by_tail.update({tail: (ident, initial) for tail, ident, initial in rows})
    start = torch.tensor(
        [by_tail[t][1] or initial_crack_m for t in data.tails], dtype=torch.float64
    )  # (tails,)
    return History(
        data,
        inspections,
        [by_tail[t][0] for t in data.tails],
        split_at_repairs(data, inspections, start),
        location_id,
    )
