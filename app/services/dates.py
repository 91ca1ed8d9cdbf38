"""Dates as the service reads them: the as-of date, days since a tail's origin, flights to
calendar dates.

A forecast marches from its origin (the last recorded flight, or a repair after it) while its
horizon counts from the as-of date (app.services.forecasts.risk says why); these helpers are the one
place both ends meet, shared by the cache, the forecasts, the ranking and the pages.
"""

from __future__ import annotations

from datetime import UTC, date, datetime, timedelta

import pandas as pd

from app.config import Settings
from model import forecast as fc

_EPOCH = datetime(1970, 1, 1, tzinfo=UTC)


def days_ahead(settings: Settings) -> tuple[date, date]:
    """The as-of dates whose risk is stored ahead of the requests (fills, the worker): today's,
    and tomorrow's so that the first ranking after midnight still only reads rows."""
    today = settings.today()
    return today, today + timedelta(days=1)


def lead_days(origin: datetime, as_of: date) -> int:
    """Whole days from the origin's date (UTC) to the as-of date; 0 when the data reach it."""
    return max(0, (as_of - origin.astimezone(UTC).date()).days)


def as_of_time(as_of: date) -> datetime:
    """The as-of date as a timestamp: its start, 00:00 UTC."""
    return datetime(as_of.year, as_of.month, as_of.day, tzinfo=UTC)


def overdue(inspect_by: datetime | None, as_of: date) -> bool:
    """An inspect-by date before the as-of date is overdue (one on it is due that day)."""
    return inspect_by is not None and inspect_by.astimezone(UTC).date() < as_of


def ns(value: datetime) -> int:
    """A timestamp as int64 nanoseconds since the epoch (model.forecast's unit)."""
    return int(pd.Timestamp(value).as_unit("ns").value)


def from_ns(value_ns: int) -> datetime:
    """Nanoseconds since the epoch as a UTC timestamp (to the microsecond)."""
    return _EPOCH + timedelta(microseconds=value_ns // 1000)


def date_after(origin: datetime, flights: int | None, rate: float) -> datetime | None:
    """The date `flights` flights after origin at `rate` a day; None for None."""
    if flights is None:
        return None
    return from_ns(fc.date_after_flights(ns(origin), flights, rate))
