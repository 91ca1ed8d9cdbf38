"""What an advance of cached rows reads of their tails' flights (app.services.forecasts.cache_advance):
whether a row can advance, its flights after its origin, its tail's utilization after them,
each at the row's location and under its version's law.

A tail's rows at its locations (one version each) stand on the same flights and, as a rule,
the same origin, so one ingest's reads are shared by them (Reads): with four locations each
read three queries and a load window of ~1,500 flights converted one timestamp at a time.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Any

import numpy as np
import pandas as pd
from sqlalchemy import Select, func, select
from sqlalchemy.orm import Session

from app.config import Settings
from app.services.dates import from_ns, ns
from app.services.forecasts.cache_rows import CacheState
from app.services.records import locations, spectra
from app.services.records.stored_spectra import reduced_ranges
from app.tables import DEFAULT_LOCATION_ID, Flight, FlightBlock, Inspection
from model import forecast as fc
from model.posterior import LocationPosterior


@dataclass
class Reads:
    """What one catch_up (app.services.forecasts.cache_advance) read of its aircraft's flights, by
    (aircraft, origin or window start), for the aircraft's rows at its other locations."""

    origins: dict[tuple[int, datetime], tuple[int | None, bool]] = field(default_factory=dict)
    after: dict[tuple[int, datetime], Sequence[Any]] = field(default_factory=dict)
    windows: dict[tuple[int, datetime], Sequence[Any]] = field(default_factory=dict)


def advanceable(
    session: Session, rows: Sequence[CacheState], reads: Reads | None = None
) -> tuple[list[CacheState], list[int]]:
    """Split rows into those that can advance and the aircraft ids that must be recomputed (a
    flight added at or before the origin, or an inspection after the first new flight)."""
    reads = reads or Reads()
    good, redo = [], []
    for row in rows:
        key = (row.aircraft_id, row.origin)
        if key not in reads.origins:
            reads.origins[key] = _at_origin(session, row)
        up_to_origin, inspected_after = reads.origins[key]
        if up_to_origin == row.flights_flown and not inspected_after:
            good.append(row)
        else:
            redo.append(row.aircraft_id)
    return good, redo


def _at_origin(session: Session, row: CacheState) -> tuple[int | None, bool]:
    """The row's tail's flights up to its origin, and whether an inspection lies after the
    first flight after it."""
    up_to_origin = session.scalar(
        select(func.count())
        .select_from(Flight)
        .where(Flight.aircraft_id == row.aircraft_id, Flight.flown_at <= row.origin)
    )
    first_new = session.scalar(
        select(func.min(Flight.flown_at)).where(
            Flight.aircraft_id == row.aircraft_id, Flight.flown_at > row.origin
        )
    )
    # an inspection observes the flights before it: one after the first new flight now
    # counts flights the row has not (its tail's growth posterior moves); one between the
    # origin and the first new flight counts what it did when the row was computed
    inspected_after = first_new is not None and session.scalar(
        select(func.count())
        .select_from(Inspection)
        .where(Inspection.aircraft_id == row.aircraft_id, Inspection.inspected_at > first_new)
    )
    return up_to_origin, bool(inspected_after)


def flights_after(
    session: Session, row: CacheState, posterior: LocationPosterior, reads: Reads
) -> tuple[np.ndarray, np.ndarray]:
    """(epoch ns, stress MPa at the row's location) of the row's tail's flights after its
    origin, in the order of model.training_data.assemble (time, then flight id); a flight
    stored as cycles at their range under the version's law (as the fill reads them)."""
    key = (row.aircraft_id, row.origin)
    if key not in reads.after:
        reads.after[key] = session.execute(
            _loads()
            .where(Flight.aircraft_id == row.aircraft_id, Flight.flown_at > row.origin)
            .order_by(Flight.flown_at, Flight.flight_id)
        ).all()
    found = reads.after[key]
    times = _epoch_ns([t for t, *_ in found])
    return times, _local(session, row, _ranges(session, found, posterior), [f[2] for f in found])


def _epoch_ns(times: list[datetime]) -> np.ndarray:
    """(flights,) int64 ns since the epoch of timezone-aware timestamps (dates.ns, at once:
    one at a time it cost ~3 us a flight, a load window's 1,500 flights per location)."""
    if not times:
        return np.zeros(0, dtype=np.int64)
    return np.asarray(pd.to_datetime(times, utc=True).as_unit("ns").asi8, dtype=np.int64)


def _loads() -> Select[datetime, float, str | None, int | None, int | None]:
    """Flights' times, ranges, missions and where their stored cycles are (None: recorded as
    one range; app.services.records.spectra)."""
    return select(
        Flight.flown_at,
        Flight.stress_range_mpa,
        Flight.mission,
        FlightBlock.spectrum_block_id,
        FlightBlock.spectrum_index,
    ).outerjoin(FlightBlock, FlightBlock.flight_pk == Flight.id)


def _ranges(session: Session, found: Sequence[Any], posterior: LocationPosterior) -> np.ndarray:
    """(flights,) the ranges of _loads() rows under the model's law."""
    stress = np.array([f[1] for f in found], dtype=np.float64)
    blobs = spectra.blobs_of(session, [f[3] for f in found], [f[4] for f in found])
    return reduced_ranges(stress, blobs, posterior.growth_law, posterior.law.constants)


def _local(
    session: Session, row: CacheState, stress: np.ndarray, missions: list[str | None]
) -> np.ndarray:
    """Recorded stress ranges as the row's location sees them (app.services.records.locations)."""
    if row.location_id == DEFAULT_LOCATION_ID:
        return stress
    location = locations.location_by_id(session, row.location_id)
    return locations.scaled(stress, pd.Series(missions, dtype=object), location)


def utilization(
    session: Session,
    row: CacheState,
    new_times: np.ndarray,
    settings: Settings,
    posterior: LocationPosterior,
    reads: Reads,
) -> fc.Utilization:
    """The tail's utilization after its new flights: the load window's flights read back (the
    longer of the two windows), with its first flight in front when the window does not reach it
    (it only sets the days covered)."""
    last = int(new_times[-1])
    days = max(settings.utilization_window_days, settings.load_window_days)
    window_start = from_ns(last - int(days * fc.NS_PER_DAY))
    key = (row.aircraft_id, window_start)
    if key not in reads.windows:
        reads.windows[key] = session.execute(
            _loads()
            .where(
                Flight.aircraft_id == row.aircraft_id,
                Flight.flown_at >= window_start - timedelta(days=1),
            )
            .order_by(Flight.flown_at, Flight.flight_id)
        ).all()
    found = reads.windows[key]
    times = _epoch_ns([t for t, *_ in found]).tolist()
    stress = _local(
        session, row, _ranges(session, found, posterior), [f[2] for f in found]
    ).tolist()
    first = ns(row.first_flown_at)
    if not times or times[0] != first:
        times, stress = [first, *times], [0.0, *stress]
    return fc.recent_utilization(
        np.array(times, dtype=np.int64),
        np.array(stress, dtype=np.float64),
        settings.utilization_window_days,
        settings.load_window_days,
    )
