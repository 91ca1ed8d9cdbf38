"""Which aircraft carry which locations: the one SQL condition every reader of a location's
subjects applies (an aircraft without a listed subset carries the whole catalogue;
app.services.records.aircraft_locations keeps the subsets)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from typing import Any

from sqlalchemy import ColumnElement, exists, func, select
from sqlalchemy.orm import Session

from app.tables import Aircraft, AircraftLocation


def carries(location_id: int | Any) -> ColumnElement[bool]:
    """Aircraft (Aircraft.id) that carry the location (an id, or a SQL expression giving one):
    those that list it, and those that list none."""
    listed = AircraftLocation.aircraft_id == Aircraft.id
    return ~exists().where(listed) | exists().where(
        listed, AircraftLocation.location_id == location_id
    )


def carrier_counts(session: Session, location_ids: Sequence[int]) -> dict[int, int]:
    """How many aircraft carry each of these locations (the catalogue page's count: the
    default location, carried by every aircraft until they list their own, may be carried by
    none)."""
    aircraft = session.scalar(select(func.count(Aircraft.id))) or 0
    listed = session.execute(
        select(AircraftLocation.aircraft_id, AircraftLocation.location_id)
    ).all()
    listing = {aircraft_id for aircraft_id, _ in listed}
    per_location = Counter(location_id for _, location_id in listed)
    return {i: aircraft - len(listing) + per_location[i] for i in location_ids}
