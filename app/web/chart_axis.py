"""A tail chart's x axis: calendar dates, or flights flown (a coupon's or component's blocks of
cycles, where a test's clock says nothing: docs/real-test-data.md).

Recorded points carry both (a history point: its date and the flights flown by then; an
inspection: the flights flown before it); a date the forecast reaches (the as-of date,
inspect-by) is read on the flights axis at the forecast's own rate, by interpolating its daily
trajectory's (date, flights) pairs.
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import datetime
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes

ChartAxis = Literal["date", "flights"]
CHART_AXES: tuple[ChartAxis, ...] = ("date", "flights")


def day_numbers(dates: Sequence[datetime]) -> Any:
    """Dates as matplotlib's day numbers (the date axis' unit)."""
    from matplotlib import dates as mdates

    return mdates.date2num(list(dates))


class TailAxis:
    """Where a point of the tail's chart lies on `kind`; points: the (dates, flights) of its
    history and forecast in time order, which other dates are read against on the flights
    axis."""

    def __init__(self, kind: ChartAxis, points: tuple[Sequence[datetime], Sequence[int]]) -> None:
        if kind not in CHART_AXES:
            raise ValueError(f"axis must be one of {CHART_AXES}, got {kind!r}")
        self.kind = kind
        dates, flights = points
        self._days = day_numbers(dates) if len(dates) else np.zeros(0)
        self._flights = np.asarray(flights, dtype=np.float64)

    def of(self, dates: Sequence[datetime], flights: Sequence[int | None]) -> Any:
        """x of points recorded at these dates after these flights."""
        if self.kind == "date":
            return day_numbers(dates)
        return np.asarray([np.nan if f is None else f for f in flights], dtype=np.float64)

    def at(self, moment: datetime) -> float:
        """x of a date (on the flights axis: between the points, or past the last at the rate of
        the points' span)."""
        day = float(day_numbers([moment])[0])
        if self.kind == "date":
            return day
        if len(self._days) < 2:
            return float(self._flights[0]) if len(self._flights) else float("nan")
        slope = (self._flights[-1] - self._flights[0]) / (self._days[-1] - self._days[0])
        if day > self._days[-1]:  # past the horizon: at the forecast's rate
            return float(self._flights[-1] + slope * (day - self._days[-1]))
        return float(np.interp(day, self._days, self._flights))

    def label(self, axes: Axes) -> None:
        """Ticks and label: ISO dates, or flights counted from the first recorded one."""
        from matplotlib import dates as mdates

        if self.kind == "flights":
            axes.set_xlabel("flights flown (a test's blocks of cycles)")
            return
        locator = mdates.AutoDateLocator(minticks=4, maxticks=8)
        axes.xaxis.set_major_locator(locator)
        axes.xaxis.set_major_formatter(mdates.DateFormatter("%Y-%m-%d"))
