"""Decisions per aircraft: every location's forecast in one line, and the governing one.

An aircraft is inspected where it is most at risk: the governing location has the highest
P(critical within the horizon), ties broken by the earliest inspect-by (none last), then by
name.  The summary lists every location with an active version of its own (app.services.models),
governing first; an aircraft whose only location is the default one has no summary, so its
answers stay exactly as before locations.

A line is read from its location's cached row alone (its stored risk of the horizon; sampled
and stored only where missing), never through the location's full forecast: that read the
row's bands (tens of KB of JSON), sampled them where an ingest had left them pending, and made
~10 queries, so an aircraft's cold answer cost ~3x one location's under the load benchmark.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import date, datetime
from typing import Any

from sqlalchemy import bindparam, func, select
from sqlalchemy.orm import Session, aliased

from app.config import Settings
from app.default_location import DEFAULT_LOCATION
from app.services import models as model_service
from app.services.forecasts import cache_rows, location_notes
from app.services.forecasts import forecast as forecast_service
from app.services.forecasts.cache_rows import Subject
from app.services.forecasts.forecast_cache import cached_state
from app.services.forecasts.residual_now import LineStrength, line_strength
from app.services.forecasts.risk import cached_risk, check_sampled, decisions, fill_risk
from app.services.forecasts.tail_status import below_critical
from app.services.records.carriage import carries
from app.services.records.locations import location_by_id
from app.tables import Aircraft, Forecast, Location, ModelVersion


@dataclass(frozen=True)
class LocationSummary:
    """One location's forecast of a tail, in the fields a decision reads."""

    location: str
    model_version: int
    crack_as_of_m: float | None  # p50 on the as-of date; None at or past critical
    critical_crack_m: float
    prob_critical: float
    inspect_by: datetime | None
    overdue: bool
    past_critical: bool
    row_stamp: int | None = None  # the cached row it came from (None: not a function of one)
    # at crack_as_of's p50, where the location gives a limit stress (None: it gives none)
    residual_strength: LineStrength | None = None


def governing_key(summary: LocationSummary) -> tuple[Any, ...]:
    """Most governing first: highest P(critical), earliest inspect-by (none last), name."""
    by = summary.inspect_by
    return (-summary.prob_critical, by is None, by or datetime.max, summary.location)


@dataclass(frozen=True)
class Carried:
    """What an aircraft's answer is kept under, read in one query (its_locations): each
    location the tail carries with its active version and the stamp of the tail's row of it
    (None: no active version, or no row yet), by name, and how many versions are active."""

    lines: tuple[tuple[str, int, int | None, int | None], ...]  # (name, id, version, stamp)
    active: int
    aircraft_id: int | None  # None: unknown tail

    @property
    def default_active(self) -> bool:
        """Whether the tail carries the default location and it has an active version."""
        return any(n == DEFAULT_LOCATION and v is not None for n, _, v, _ in self.lines)

    @property
    def unassessable(self) -> bool:
        """The tail carries locations, none with an active version, and not the default one
        (whose own forecast would say that no model is active)."""
        return (
            self.aircraft_id is not None
            and bool(self.lines)
            and all(version is None for _, _, version, _ in self.lines)
            and not any(name == DEFAULT_LOCATION for name, _, _, _ in self.lines)
        )

    @property
    def several(self) -> bool:
        """Whether the aircraft's answer summarises its locations: more than one version is
        active, or the tail's default location has none while another it carries does (the
        answer is then its governing location's)."""
        if self.aircraft_id is None:
            return False
        assessed = any(version is not None for _, _, version, _ in self.lines)
        return assessed and (self.active > 1 or not self.default_active)

    @property
    def unassessed(self) -> tuple[str, ...]:
        """The carried locations without an active version (app.services.records.aircraft_locations)."""
        return tuple(name for name, _, version, _ in self.lines if version is None)

    def default_stamp(self) -> tuple[int, int] | None:
        """(active version, its row's stamp) at the default location, as app.services.forecasts.forecast.
        current_stamp reads it (None: no active version or no stamped row) where the tail
        carries it (carries_default)."""
        for name, _, version, stamp in self.lines:
            if name == DEFAULT_LOCATION and version is not None and stamp is not None:
                return version, stamp
        return None

    @property
    def carries_default(self) -> bool:
        """Whether the tail carries the default location (its line is read)."""
        return any(name == DEFAULT_LOCATION for name, _, _, _ in self.lines)

    def stamps(self) -> tuple[tuple[str, int, int], ...] | None:
        """(location, version, its row's stamp) of each line `summarise` lists; None where a
        row is missing or unstamped."""
        out = []
        for name, _, version, stamp in self.lines:
            if version is None:
                continue
            if stamp is None:
                return None
            out.append((name, version, stamp))
        return tuple(out)


_ACTIVE = ModelVersion.status == "active"
_ANY = aliased(ModelVersion)
# built once (as app.services.records.aircraft_locations' query, and for the same reason)
_CARRIED = (
    select(
        Location.name,
        Location.id,
        ModelVersion.version,
        Forecast.stamp,
        select(func.count()).select_from(_ANY).where(_ANY.status == "active").scalar_subquery(),
        Aircraft.id,
    )
    .select_from(Location)
    .join(Aircraft, Aircraft.tail == bindparam("tail"))
    .outerjoin(ModelVersion, (ModelVersion.location_id == Location.id) & _ACTIVE)
    .outerjoin(
        Forecast,
        (Forecast.aircraft_id == Aircraft.id)
        & (Forecast.location_id == Location.id)
        & (Forecast.model_version == ModelVersion.version),
    )
    .where(carries(Location.id))
    .order_by(Location.name)
)


def its_locations(session: Session, tail: str) -> Carried:
    """The tail's carried locations, their active versions and row stamps (Carried), in one
    query: the aircraft's kept answer is checked on every request (it took ~12).  No lines
    for an unknown tail."""
    rows = session.connection().execute(_CARRIED, {"tail": tail}).all()
    active, aircraft_id = (int(rows[0][4]), int(rows[0][5])) if rows else (0, None)
    return Carried(tuple((r[0], r[1], r[2], r[3]) for r in rows), active, aircraft_id)


def summarise(
    session: Session,
    carried: Carried,
    *,
    horizon_days: int,
    as_of: date,
    settings: Settings,
    default: forecast_service.TailForecast | None,
) -> list[LocationSummary] | None:
    """The carried locations (its_locations) with an active version, governing first; None
    where the default location is the only one (nothing to summarise).  default: the default
    location's forecast for the same horizon and as-of date (not made again; None where the
    tail's default location has no active version); the others' lines are read from their
    rows.  Raises ConflictError (a location's row could not be made: no flights)."""
    if not carried.several or carried.aircraft_id is None:
        return None
    out = []
    for name, location_id, version, _ in carried.lines:
        if version is None:
            continue
        if name == DEFAULT_LOCATION and default is not None:
            out.append(_line_of(default))
        else:
            subject = Subject(carried.aircraft_id, location_id)
            out.append(_line(session, subject, name, version, horizon_days, as_of, settings))
    return sorted(out, key=governing_key)


def _line_of(result: forecast_service.TailForecast) -> LocationSummary:
    """A location's line from its full forecast."""
    critical = result.critical_crack_m
    return LocationSummary(
        location=DEFAULT_LOCATION,
        model_version=result.model_version,
        crack_as_of_m=below_critical(result.crack_as_of.p50, critical),
        critical_crack_m=critical,
        prob_critical=result.risk.prob_critical,
        inspect_by=result.inspect_by,
        overdue=result.overdue,
        past_critical=result.past.past_critical,
        row_stamp=result.stamp,
        residual_strength=LineStrength.of(result.residual_strength),
    )


def _line(
    session: Session,
    subject: Subject,
    name: str,
    version: int,
    horizon_days: int,
    as_of: date,
    settings: Settings,
) -> LocationSummary:
    """A location's line from its row's stored risk, as its forecast (forecast_tail) reports
    the same fields; the risk sampled and stored first where the row lacks it (the line then
    names no row: an answer is kept only where every line read its risk stored)."""
    state = cached_state(session, subject, version, settings, bands=False)
    posterior = model_service.load_posterior(session, version)
    risk = cached_risk(state, horizon_days, settings, as_of)
    stamp = state.stamp
    if risk is None:
        check_sampled([state], horizon_days, settings, as_of)
        fill_risk(posterior, [state], horizon_days, settings, bands=False, as_of=as_of)
        cache_rows.store_risk(session, [state], bands=False)
        session.commit()
        risk = cached_risk(state, horizon_days, settings, as_of)
        stamp = None
    assert risk is not None
    critical = posterior.law.critical_crack_m
    decided = decisions(state.origin, risk, state.flights_per_day, critical, as_of)
    return LocationSummary(
        location=name,
        model_version=version,
        crack_as_of_m=below_critical(risk.crack_as_of[1], critical),
        critical_crack_m=critical,
        prob_critical=risk.prob_critical,
        inspect_by=decided.inspect_by,
        overdue=decided.overdue,
        past_critical=decided.past.past_critical,
        row_stamp=stamp,
        residual_strength=line_strength(
            location_by_id(session, subject.location_id), risk.crack_as_of[1], settings
        ),
    )


def stamps_of(summary: list[LocationSummary]) -> tuple[tuple[str, int, int], ...] | None:
    """Carried.stamps as the summary's own rows had them; None where a line had no row."""
    out = []
    for line in sorted(summary, key=lambda s: s.location):
        if line.row_stamp is None:
            return None
        out.append((line.location, line.model_version, line.row_stamp))
    return tuple(out)


def aircraft_location(
    session: Session, tail: str, *, horizon_days: int, as_of: date, settings: Settings
) -> str | None:
    """The location whose forecast an aircraft's answer is (its image, its page's first
    chart, a planned forecast): None (the default one) where the tail carries it with an
    active version or carries nothing with one (whose forecast then says why), else the
    governing one of those it carries.  Raises ConflictError where no location it carries
    has an active version and it does not carry the default one."""
    carried = its_locations(session, tail)
    if carried.unassessable:
        assert carried.aircraft_id is not None
        found = location_notes.notes(
            session, carried.aircraft_id, carried.lines, inspected_too=False
        )
        raise location_notes.no_model_anywhere(tail, found)
    if carried.default_active or not carried.several:
        return None
    summary = summarise(
        session, carried, horizon_days=horizon_days, as_of=as_of, settings=settings, default=None
    )
    return None if not summary else summary[0].location
