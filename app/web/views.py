"""What the templates and charts are given: service results turned into rows, marks and series."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal, get_args

from app.services.crack_history import CrackHistory
from app.tables import Inspection
from app.web.charts import HistoryCurve, InspectionMark, Series
from app.web.format import mm
from app.web.source import RankedTail, TailForecast

SortKey = Literal["rank", "tail", "crack", "prob", "critical", "inspect", "inspected"]
SORT_KEYS: tuple[str, ...] = get_args(SortKey)
# The first click on a column sorts the most urgent first: large numbers, early dates.
_FIRST_DESCENDING = {"crack", "prob"}


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
    Column("inspected", "Last inspection", "Latest recorded inspection and its finding"),
)


def _sort_value(key: str, row: FleetRow) -> Any:
    item = row.item
    values: dict[str, Callable[[], Any]] = {
        "rank": lambda: row.rank,
        "tail": lambda: item.tail,
        "crack": lambda: item.risk.crack_as_of[1],
        "prob": lambda: item.risk.prob_critical,
        "critical": lambda: item.critical_dates[1] or item.critical_dates[0],
        "inspect": lambda: item.inspect_by,
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


def sort_link(column: str, *, sort: str, descending: bool) -> str:
    """The query of a column header's link: the other direction when it is the sorted column."""
    flip = not descending if column == sort else column in _FIRST_DESCENDING
    return f"?sort={column}" + ("&order=desc" if flip else "")


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
    )


def history_curve(history: CrackHistory) -> HistoryCurve:
    return HistoryCurve(dates=history.dates, crack_m=history.crack_m)


def inspection_marks(inspections: list[Inspection]) -> list[InspectionMark]:
    """Measured cracks, non-detections at their detection limit (the crack lay below it) and
    repairs at the crack they restart from."""
    marks = []
    for i in inspections:
        if i.detected:
            marks.append(InspectionMark(i.inspected_at, "measured", i.crack_length_m))
        else:
            limit = i.detection_threshold_m or i.pod_a90_m or i.pod_a50_m
            marks.append(InspectionMark(i.inspected_at, "not-found", limit))
        if i.repaired:
            marks.append(InspectionMark(i.inspected_at, "repair", i.crack_after_repair_m))
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
