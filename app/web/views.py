"""What the templates and charts are given: service results turned into rows, marks and series."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any, Literal, get_args
from urllib.parse import urlencode

from app.services.forecasts.crack_history import CrackHistory
from app.tables import Inspection
from app.web.charts import Compared, HistoryCurve, InspectionMark, Series
from app.web.format import mm
from app.web.source import RankedTail, TailForecast

SortKey = Literal[
    "rank", "tail", "crack", "prob", "margin", "critical", "inspect", "age", "inspected"
]
SORT_KEYS: tuple[str, ...] = get_args(SortKey)
# The first click on a column sorts the most urgent first: large numbers, early dates.
_FIRST_DESCENDING = {"crack", "prob", "age"}


@dataclass(frozen=True)
class FleetRow:
    rank: int
    item: RankedTail
    overdue: bool


@dataclass(frozen=True)
class Column:
    key: str
    label: str
    title: str


COLUMNS = (
    Column("rank", "#", "Rank by risk: P(critical within the horizon), then p95 crack now"),
    Column("tail", "Tail", "Aircraft tail number"),
    Column("crack", "Crack today (mm)", "Projected crack on the as-of date: p50, p05–p95"),
    Column("prob", "P(critical)", "Probability that the crack reaches a_crit within the horizon"),
    Column("critical", "Critical date", "Sampled date the crack reaches a_crit: p50, p05–p95"),
    Column("inspect", "Inspect by", "Last flight + half the p05 time to a_crit"),
    Column(
        "age", "Data age", "Days from the last recorded flight and inspection to the as-of date"
    ),
    Column("inspected", "Last inspection", "Latest recorded inspection and its finding"),
)
# after P(critical), where some row's location gives a limit stress (columns_of)
MARGIN = Column(
    "margin",
    "Strength margin",
    "Margin of the residual strength at the p50 crack today over the location's limit stress "
    "(strength / limit - 1), with the strength and what sets it",
)


def columns_of(items: list[RankedTail]) -> tuple[Column, ...]:
    """The fleet table's columns: COLUMNS, with MARGIN where some row has a residual strength
    (a fleet without limit stresses shows its table as before)."""
    if all(item.residual_strength is None for item in items):
        return COLUMNS
    after = [c.key for c in COLUMNS].index("prob") + 1
    return (*COLUMNS[:after], MARGIN, *COLUMNS[after:])


def _sort_value(key: str, row: FleetRow) -> Any:
    item = row.item
    values: dict[str, Callable[[], Any]] = {
        "rank": lambda: row.rank,
        "tail": lambda: item.tail,
        "crack": lambda: item.risk.crack_as_of[1],
        "prob": lambda: item.risk.prob_critical,
        "margin": lambda: item.residual_strength and item.residual_strength.margin,
        "critical": lambda: item.critical_dates[1] or item.critical_dates[0],
        "inspect": lambda: item.inspect_by,
        "age": lambda: item.data_age.days_since_last_flight,
        "inspected": lambda: item.last_inspection and item.last_inspection.inspected_at,
    }
    return values[key]()


def fleet_rows(items: list[RankedTail], *, sort: str, descending: bool) -> list[FleetRow]:
    """The ranking's tails as table rows sorted by a column; tails without a value come last."""
    if sort not in SORT_KEYS:
        raise ValueError(f"sort must be one of {SORT_KEYS}, got {sort!r}")
    rows = [FleetRow(rank, item, item.overdue) for rank, item in enumerate(items, start=1)]
    known = [r for r in rows if _sort_value(sort, r) is not None]
    unknown = [r for r in rows if _sort_value(sort, r) is None]
    known.sort(key=lambda r: (_sort_value(sort, r), r.rank), reverse=descending)
    return known + unknown


def sort_link(
    column: str, *, sort: str, descending: bool, keep: Mapping[str, Any] | None = None
) -> str:
    """The query of a column header's link: the other direction when it is the sorted column;
    `keep`: the page's other parameters (search, filter, as-of), kept as they are."""
    flip = not descending if column == sort else column in _FIRST_DESCENDING
    return page_query({**(keep or {}), "sort": column, "order": "desc" if flip else None})


def page_query(params: Mapping[str, Any]) -> str:
    """`?a=1&b=2` of the parameters that are set (None and "" left out)."""
    given = {k: v for k, v in params.items() if v is not None and v != ""}
    return "?" + urlencode(given) if given else "?"


# The fleet page's filters: each card's count is the number of rows its filter shows.
Show = Literal["all", "overdue", "due", "stale", "flagged", "past-critical"]
SHOWS: tuple[str, ...] = get_args(Show)


def search(rows: list[FleetRow], query: str | None) -> list[FleetRow]:
    """Rows whose tail contains `query` (case and surrounding blanks ignored); all for none."""
    wanted = (query or "").strip().upper()
    return [r for r in rows if wanted in r.item.tail.upper()] if wanted else rows


def shows(row: FleetRow, show: str, *, now: datetime, due_days: int) -> bool:
    """Whether the filter `show` keeps the row: overdue; due within due_days of now (overdue
    ones included: they are due too); stale data; flagged inspections; past critical.  Raises
    ValueError for another filter."""
    item = row.item
    if show not in SHOWS:
        raise ValueError(f"show must be one of {SHOWS}, got {show!r}")
    due = item.inspect_by is not None and item.inspect_by <= now + timedelta(days=due_days)
    kept = {
        "all": True,
        "overdue": row.overdue,
        "due": due,
        "stale": item.data_age.stale,
        "flagged": bool(item.flagged_inspection_ids),
        "past-critical": item.past.past_critical,
    }
    return kept[show]


def counts(rows: list[FleetRow], *, now: datetime, due_days: int) -> dict[str, int]:
    """For each filter, how many aircraft it shows a row of (a tail's rows at several
    locations count once: the cards count aircraft, not rows)."""
    return {
        show: len({r.item.tail for r in rows if shows(r, show, now=now, due_days=due_days)})
        for show in SHOWS
    }


@dataclass(frozen=True)
class LocationModel:
    """A location the fleet page's rows come from: its active version and a_crit."""

    name: str
    model_version: int
    critical_crack_m: float


def location_models(tails: list[RankedTail]) -> list[LocationModel]:
    """The locations of (tail, location) rows, by name (empty: rows of one location)."""
    seen: dict[str, LocationModel] = {}
    for item in tails:
        if item.location is None or item.location in seen:
            continue
        version, critical = item.model_version, item.critical_crack_m
        if version is not None and critical is not None:
            seen[item.location] = LocationModel(item.location, version, critical)
    return [seen[name] for name in sorted(seen)]


def tail_series(forecast: TailForecast) -> Series:
    points = forecast.trajectory
    return Series(
        tail=forecast.tail,
        dates=[p.date for p in points],
        crack_m=[p.crack_length_m for p in points],
        p05=[p.p05 for p in points],
        p50=[p.p50 for p in points],
        p95=[p.p95 for p in points],
        prob_critical=forecast.risk.prob_critical,
        flights=[p.flights for p in points],
    )


def history_curve(history: CrackHistory) -> HistoryCurve:
    return HistoryCurve(dates=history.dates, crack_m=history.crack_m, flights=history.flights)


def inspection_marks(
    inspections: list[Inspection], history: CrackHistory | None = None
) -> list[InspectionMark]:
    """Measured cracks, non-detections at their detection limit (the crack lay below it) and
    repairs at the crack they restart from, each after the flights flown before it (history);
    a flagged finding carries its z and what it was compared with (app.services.forecasts.assessment:
    the estimate after the last recorded flight before it)."""
    marks = []
    for i in inspections:
        z = i.forecast_z if i.flagged else None
        flown = None if history is None else history.flights_before(i.inspected_at)
        compared = None
        last = None if history is None else history.last_flight_before(i.inspected_at)
        if z is not None and i.forecast_crack_m is not None and last is not None:
            compared = Compared(i.forecast_crack_m, last, flown or 0)
        if i.detected:
            marks.append(
                InspectionMark(i.inspected_at, "measured", i.crack_length_m, z, flown, compared)
            )
        else:
            limit = i.detection_threshold_m or i.pod_a90_m or i.pod_a50_m
            marks.append(InspectionMark(i.inspected_at, "not-found", limit, z, flown, compared))
        if i.repaired:
            marks.append(
                InspectionMark(i.inspected_at, "repair", i.crack_after_repair_m, flights=flown)
            )
    return marks


def inspection_finding(inspection: Inspection) -> str:
    """One inspection's result in words, crack sizes in mm."""
    if inspection.detected:
        found = f"{mm(inspection.crack_length_m)} mm"
    else:
        limit = inspection.detection_threshold_m or inspection.pod_a90_m or inspection.pod_a50_m
        found = "nothing found" + (f" (limit {mm(limit)} mm)" if limit else "")
    if inspection.repaired:
        found += f"; repaired to {mm(inspection.crack_after_repair_m)} mm"
    return found


def governing_location(forecasts: list[tuple[str, TailForecast]]) -> str:
    """The governing one of a tail's locations, as its JSON answer names it
    (app.services.forecasts.aircraft_summary.governing_key): highest P(critical), earliest inspect-by
    (none last), then by name."""

    def key(pair: tuple[str, TailForecast]) -> tuple[Any, ...]:
        name, at = pair
        by = at.inspect_by
        return (-at.risk.prob_critical, by is None, by or datetime.max.replace(tzinfo=None), name)

    return min(forecasts, key=key)[0]
