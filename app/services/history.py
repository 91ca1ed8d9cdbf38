"""A batch of tails' recorded history, loaded once for training (retrain) and forecasting.

Flights and inspections come back through app.services.records; each tail's history is split at
its repairs (app.services.segments), its first segment starting at the tail's initial crack, or
the law's a0 where none is set.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import pandas as pd
import torch
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.services.locations import local_stress, location_by_id
from app.services.records import stored_flights, stored_inspections
from app.services.segments import Segments, split_at_repairs
from app.storage import chunks
from app.tables import DEFAULT_LOCATION_ID, Aircraft
from model.training_data import TrainingData, assemble


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


def load_history(
    session: Session,
    aircraft_ids: Sequence[int],
    *,
    initial_crack_m: float,
    location_id: int = DEFAULT_LOCATION_ID,
) -> History | None:
    """The history of these aircraft at one location (those without flights left out): the
    recorded loads scaled to the location (app.services.locations.local_stress) and its own
    inspections; None when none has any flights.

    initial_crack_m: the crack a tail without its own initial crack starts from (the law's a0).
    """
    flights = stored_flights(session, aircraft_ids)
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
