"""GET forecasts' answers, kept per process under their tail's cached row's stamp.

An answer (~62 KB at the default horizon) is a function of its tail's cached row, the version,
the settings, the horizon and the as-of date (app.services.forecasts.forecast.current_stamp says why), so
each process keeps the encoded answer under the row's stamp (app.services.memo) and serves it
while the stamp read in the request's own transaction is the same: a hit costs one small query
instead of the march, 366 points built and validated, and their encoding (7.3 -> 1.5 ms of CPU
a request, benchmarks/RESULTS.md).  Two horizons of a 600-tail fleet, ~75 MB at most.  The
aircraft's answer with several locations is a function of each one's row, so it is kept under
all their stamps: recomputed every time, it cost 85 ms against 6 ms for one location, and
under the load benchmark forecasts waited seconds.  The aircraft's answer also names the
carried locations without a model, which no row's stamp follows, so the names are part of what
an answer is kept under; both are read in one query (app.services.forecasts.aircraft_summary.
its_locations: the ~12 it took were most of a kept answer's time).  A one-location answer's
stamp is its default line's there, and its notes are read only where a line has something to
note: a kept answer is one query (three, under the load benchmark's profile, were nine tenths
of its route's time).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from datetime import date

from sqlalchemy.orm import Session

from app.config import Settings
from app.default_location import DEFAULT_LOCATION
from app.services.forecasts import aircraft_summary, location_notes
from app.services.forecasts import forecast as forecast_service
from app.services.forecasts.reports import ForecastReport, forecast_report
from app.services.forecasts.risk import inspect_rule
from app.services.memo import StampedMemo

# answers a process keeps (two horizons of a 600-tail fleet)
KEPT = 1200
_ANSWERS: StampedMemo[bytes] = StampedMemo(KEPT)


@dataclass(frozen=True)
class _Asked:
    """What an answer is kept under (key, and the stamps of the rows it reads: None where one
    is missing or unstamped), the tail's carried locations (None: one location's answer was
    asked), their notes (app.services.forecasts.location_notes) and the body kept under them (None:
    none)."""

    key: tuple[object, ...]
    current: tuple[object, ...] | None
    carried: aircraft_summary.Carried | None
    notes: tuple[location_notes.LocationNote, ...]
    body: bytes | None

    @property
    def unassessed(self) -> tuple[str, ...]:
        return () if self.carried is None else self.carried.unassessed


def _asked(
    session: Session,
    tail: str,
    location: str | None,
    horizon_days: int,
    as_of: date,
    settings: Settings,
) -> _Asked:
    # the aircraft's answer summarises every location with a model: a function of their rows,
    # and of which carried locations have none or were never inspected (a catalogue entry, a
    # tail's subset or a version's status changes it)
    carried = aircraft_summary.its_locations(session, tail) if location is None else None
    several = carried is not None and carried.several
    notes: tuple[location_notes.LocationNote, ...] = ()
    if carried is not None and carried.aircraft_id is not None:
        notes = location_notes.notes(
            session, carried.aircraft_id, carried.lines, inspected_too=several
        )
        if carried.unassessable:
            raise location_notes.no_model_anywhere(tail, notes)
    current: tuple[object, ...] | None
    if carried is not None and carried.several:
        current = carried.stamps()
    elif carried is not None and carried.carries_default:
        # its_locations read the default location's row with the rest: not read again
        current = carried.default_stamp()
    else:
        current = forecast_service.current_stamp(session, tail, location)
    key = (str(session.get_bind().engine.url), tail, location, horizon_days, as_of, several)
    body = None if current is None else _ANSWERS.get(key, (*current, notes, settings))
    return _Asked(key, current, carried, notes, body)


def encoded_forecast(
    session: Session,
    tail: str,
    *,
    horizon_days: int,
    as_of: date,
    settings: Settings,
    encode: Callable[[ForecastReport], bytes],
    location: str | None = None,
) -> bytes:
    """The tail's forecast at the location (app.services.forecasts.forecast.forecast_tail) as `encode`
    writes its report, from the memo while its row is unchanged.  Raises NotFoundError,
    ConflictError."""
    asked = _asked(session, tail, location, horizon_days, as_of, settings)
    if asked.body is not None:
        return asked.body
    return _made(session, tail, location, horizon_days, as_of, settings, encode, asked)


def kept_forecast(
    session: Session, tail: str, *, horizon_days: int, as_of: date, settings: Settings
) -> bytes | None:
    """The aircraft's answer kept under its rows' stamps as they are now (None: none is), as
    encoded_forecast would serve it without making it."""
    return _asked(session, tail, None, horizon_days, as_of, settings).body


def made_ahead(
    session: Session,
    tail: str,
    *,
    horizon_days: int,
    as_of: date,
    settings: Settings,
    encode: Callable[[ForecastReport], bytes],
) -> bool:
    """The aircraft's answer made and kept as encoded_forecast makes it, where each row it
    reads is stored (app.services.forecasts.answers_ahead); False where one is missing or unstamped:
    its fill is left to the tail's readers.  Raises NotFoundError, ConflictError."""
    asked = _asked(session, tail, None, horizon_days, as_of, settings)
    if asked.current is None:
        return False
    if asked.body is None:
        _made(session, tail, None, horizon_days, as_of, settings, encode, asked)
    return True


def _made(
    session: Session,
    tail: str,
    location: str | None,
    horizon_days: int,
    as_of: date,
    settings: Settings,
    encode: Callable[[ForecastReport], bytes],
    asked: _Asked,
) -> bytes:
    """The answer made from the rows, kept under the stamps of the rows it read."""
    carried, key, unassessed, notes = asked.carried, asked.key, asked.unassessed, asked.notes
    if carried is not None and carried.several and not carried.default_active:
        # the body is the governing location's forecast: the summary decides which
        summary = aircraft_summary.summarise(
            session,
            carried,
            horizon_days=horizon_days,
            as_of=as_of,
            settings=settings,
            default=None,
        )
        assert summary, "several: some carried location has an active version"
        location = summary[0].location
    result = forecast_service.forecast_tail(
        session,
        tail,
        horizon_days=horizon_days,
        settings=settings,
        as_of=as_of,
        location=location,
    )
    report = forecast_report(
        result,
        stale_after_days=settings.stale_after_days,
        inspect_rule=inspect_rule(settings),
        unassessed=unassessed,
        notes=notes,
    )
    if carried is not None and carried.several and carried.default_active:
        # every location's line, governing first, beside the default location's forecast
        summary = aircraft_summary.summarise(
            session,
            carried,
            horizon_days=horizon_days,
            as_of=as_of,
            settings=settings,
            default=result,
        )
    elif carried is None or not carried.several:
        summary = None
    if summary is not None:
        governing = summary[0].location
        shown = location or DEFAULT_LOCATION
        located = replace(report, governing_location=governing, locations=summary, location=shown)
        body = encode(located)
        stamps = aircraft_summary.stamps_of(summary)
        if stamps is not None:
            _ANSWERS.put(key, (*stamps, notes, settings), body)
        return body
    body = encode(report)
    if result.stamp is not None:
        _ANSWERS.put(key, (result.model_version, result.stamp, notes, settings), body)
    return body
