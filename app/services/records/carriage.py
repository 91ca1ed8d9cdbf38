"""Which aircraft carry which locations: the one SQL condition every reader of a location's
subjects applies (an aircraft without a listed subset carries the whole catalogue;
app.services.records.aircraft_locations keeps the subsets)."""

from __future__ import annotations

from typing import Any

from sqlalchemy import ColumnElement, exists

from app.tables import Aircraft, AircraftLocation


def carries(location_id: int | Any) -> ColumnElement[bool]:
    """Aircraft (Aircraft.id) that carry the location (an id, or a SQL expression giving one):
    those that list it, and those that list none."""
    listed = AircraftLocation.aircraft_id == Aircraft.id
    return ~exists().where(listed) | exists().where(
        listed, AircraftLocation.location_id == location_id
    )
