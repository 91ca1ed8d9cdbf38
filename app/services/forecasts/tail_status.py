"""What a tail's numbers cannot say by themselves: how old its data are, and whether its crack
has passed the critical one.

Data age: whole days from the tail's last recorded flight (and last inspection) to the as-of
date; a tail whose last flight lies more than `stale_after_days` (setting) before it is stale,
since its forecast then extrapolates loads nobody has seen.

Past critical: Paris' law ends at a_crit and every march holds a crack past it at a fixed bound
(model/ holds it; the plausibility bound, 0.5 m by default, where a tail ran far past), so a
crack length at or past a_crit is no measurement of anything.  Every output says it the same
way: the flag `past_critical` (the sampled p50 crack on the as-of date reached a_crit) and
`past_critical_since` (the date the p50 reached it), and reports such lengths as null.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, date, datetime

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.tables import DEFAULT_LOCATION_ID, Flight, Inspection


@dataclass(frozen=True)
class DataAge:
    """Days from the tail's last flight and last inspection (None: never inspected) to the
    as-of date (0 when the data reach it); stale: the flight age exceeds stale_after_days."""

    last_flown_at: datetime
    last_inspected_at: datetime | None
    days_since_last_flight: int
    days_since_last_inspection: int | None
    stale: bool


@dataclass(frozen=True)
class PastCritical:
    """past_critical: the p50 crack on the as-of date reached a_crit; past_critical_since: the
    date it did (None when not past critical)."""

    past_critical: bool
    past_critical_since: datetime | None


def _days_before(moment: datetime, as_of: date) -> int:
    return max(0, (as_of - moment.astimezone(UTC).date()).days)


def data_age(
    last_flown_at: datetime,
    last_inspected_at: datetime | None,
    as_of: date,
    *,
    stale_after_days: int,
) -> DataAge:
    """The data age of a tail as of `as_of`.  Raises ValueError for stale_after_days < 1."""
    if stale_after_days < 1:
        raise ValueError(f"stale_after_days must be >= 1, got {stale_after_days}")
    flight_days = _days_before(last_flown_at, as_of)
    return DataAge(
        last_flown_at=last_flown_at,
        last_inspected_at=last_inspected_at,
        days_since_last_flight=flight_days,
        days_since_last_inspection=None
        if last_inspected_at is None
        else _days_before(last_inspected_at, as_of),
        stale=flight_days > stale_after_days,
    )


def past_critical(
    crack_as_of_p50_m: float | None,
    critical_crack_m: float,
    critical_date_p50: datetime | None,
    origin: datetime,
) -> PastCritical:
    """Whether the p50 crack on the as-of date reached a_crit, and since when (the p50 critical
    date; the origin where the crack was past a_crit already there).  A p50 that is not finite
    (None) ran far past a_crit too."""
    past = crack_as_of_p50_m is None or crack_as_of_p50_m >= critical_crack_m
    if not past:
        return PastCritical(False, None)
    return PastCritical(True, critical_date_p50 or origin)


def below_critical(crack_m: float | None, critical_crack_m: float) -> float | None:
    """A crack length as outputs report it: None at or past a_crit (or not finite)."""
    if crack_m is None or crack_m >= critical_crack_m:
        return None
    return crack_m


def last_flights(session: Session, origins: Mapping[int, datetime]) -> dict[int, datetime]:
    """Each tail's last recorded flight, from its cached row's origin (last_flights_of)."""
    return dict(zip(origins, last_flights_of(session, list(origins.items())), strict=True))


def last_flights_of(session: Session, rows: Sequence[tuple[int, datetime]]) -> list[datetime]:
    """The last recorded flight of each row's tail, from the row's origin (aircraft id,
    origin): the origin is the last flight (a cache row is never behind its tail's flights,
    app.services.forecasts.forecast_cache) unless a repair dated at or after it set the origin, when
    that tail's flights are read (a scan of its flights: flown_at has no index; repairs are
    few).  Rows of one tail at several locations are read together."""
    found = [origin for _, origin in rows]
    if not rows:
        return found
    aircraft_ids = sorted({ident for ident, _ in rows})
    repairs = dict(
        session.execute(
            select(Inspection.aircraft_id, func.max(Inspection.inspected_at))
            .where(Inspection.aircraft_id.in_(aircraft_ids), Inspection.repaired)
            .group_by(Inspection.aircraft_id)
        ).all()
    )
    repaired = [
        k
        for k, (ident, origin) in enumerate(rows)
        if repairs.get(ident) is not None and repairs[ident] >= origin
    ]
    if repaired:
        flown = dict(
            session.execute(
                select(Flight.aircraft_id, func.max(Flight.flown_at))
                .where(Flight.aircraft_id.in_(sorted({rows[k][0] for k in repaired})))
                .group_by(Flight.aircraft_id)
            ).all()
        )
        for k in repaired:
            at = flown.get(rows[k][0])
            if at is not None:
                found[k] = at
    return found


def last_inspected(
    session: Session, aircraft_id: int, location_id: int = DEFAULT_LOCATION_ID
) -> datetime | None:
    """The tail's latest inspection time at the location (None: never inspected there)."""
    return session.scalar(
        select(func.max(Inspection.inspected_at)).where(
            Inspection.aircraft_id == aircraft_id, Inspection.location_id == location_id
        )
    )
