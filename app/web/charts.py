"""Forecast charts drawn on the server (matplotlib's Agg and SVG back ends; no pyplot, no network).

Two charts: one tail's crack over its forecast horizon (the point projection, the sampled
p05-p95 band, the critical crack a_crit and the tail's inspections), and the fleet's most
at-risk tails (each one's p50 crack and band against a_crit).  Both are rendered to SVG (text
kept as text, so the page stays searchable and small) or PNG.  Elements carry ids (`band`,
`forecast`, `a-crit`, `inspections-*`) that stay in the SVG for tools and tests to find.
"""

from __future__ import annotations

import io
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import TYPE_CHECKING, Any, Literal

from app.web import format as fmt
from app.web.chart_axis import ChartAxis, TailAxis, day_numbers

# matplotlib is imported at the first chart, not with the service (~1 s of every start).
if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

ImageFormat = Literal["svg", "png"]
MEDIA_TYPES: dict[str, str] = {"svg": "image/svg+xml", "png": "image/png"}

_render_lock = threading.Lock()
_STYLE: dict[Any, Any] = {
    "font.family": "DejaVu Sans",
    "font.size": 9,
    "axes.edgecolor": "#9aa5b1",
    "axes.labelcolor": "#243b53",
    "axes.titlesize": 10,
    "axes.titleweight": "bold",
    "xtick.color": "#486581",
    "ytick.color": "#486581",
    "grid.color": "#e4e7eb",
    "svg.fonttype": "none",
    "svg.hashsalt": "fleetpinn",
}
_INK = "#1f4e79"
_CRITICAL = "#c53030"
_BAND = "#63a4e0"
_BAND_EDGE = "#2b6cb0"
_PALETTE = (
    "#1f77b4",
    "#d62728",
    "#2ca02c",
    "#9467bd",
    "#ff7f0e",
    "#8c564b",
    "#e377c2",
    "#17becf",
    "#7f7f7f",
    "#bcbd22",
)


@dataclass(frozen=True)
class Series:
    """One tail's forecast: daily dates, point crack, and the sampled p05/p50/p95 (m)."""

    tail: str
    dates: Sequence[datetime]
    crack_m: Sequence[float]
    p05: Sequence[float | None]
    p50: Sequence[float | None]
    p95: Sequence[float | None]
    prob_critical: float
    flights: Sequence[int] = ()  # flights flown by each date (the flights axis)


@dataclass(frozen=True)
class HistoryCurve:
    """The estimated crack after the tail's recorded flights (m)."""

    dates: Sequence[datetime]
    crack_m: Sequence[float]
    flights: Sequence[int] = ()  # flights flown by each date (the flights axis)


@dataclass(frozen=True)
class Compared:
    """What a flagged finding was compared with (app.services.forecasts.assessment): the estimated crack
    after the last recorded flight before the inspection, that flight's date and count."""

    crack_m: float
    at: datetime
    flights: int


@dataclass(frozen=True)
class InspectionMark:
    inspected_at: datetime
    kind: Literal["measured", "not-found", "repair"]
    crack_m: float | None
    # disagreed strongly with the tail's forecast when stored (app.services.forecasts.assessment): its z
    flagged_z: float | None = None
    flights: int | None = None  # flights flown before it (the flights axis)
    compared: Compared | None = None


_days = day_numbers


def _mm(values: Sequence[float | None]) -> list[float]:
    return [float("nan") if v is None else v * 1000 for v in values]


def _figure(height_in: float) -> Figure:
    from matplotlib.figure import Figure

    return Figure(figsize=(9, height_in), layout="constrained")


def _axes(figure: Figure, title: str, x: TailAxis | None = None) -> Axes:
    axes = figure.add_subplot()
    axes.set_title(title, loc="left")
    axes.set_ylabel("crack length (mm)")
    axes.grid(True, linewidth=0.6)
    axes.spines[["top", "right"]].set_visible(False)
    (x or TailAxis("date", ((), ()))).label(axes)
    return axes


def _critical_line(axes: Axes, critical_crack_m: float) -> None:
    line = axes.axhline(
        critical_crack_m * 1000,
        color=_CRITICAL,
        linestyle="--",
        linewidth=1.2,
        label=f"a_crit {fmt.mm(critical_crack_m)} mm",
    )
    line.set_gid("a-crit")


def _flagged_marks(axes: Axes, inspections: Sequence[InspectionMark], x: TailAxis) -> None:
    """A red ring around each flagged inspection, labelled with its z (finding against the
    forecast in its spread's units), so that a surprising measurement is seen on the chart; and
    what it was compared with: the estimate after the last recorded flight before it (a
    diamond there, a dotted line to the finding), which may lie long before today's projection."""
    flagged = [m for m in inspections if m.flagged_z is not None and m.crack_m is not None]
    if not flagged:
        return
    days = x.of([m.inspected_at for m in flagged], [m.flights for m in flagged])
    cracks = [m.crack_m * 1000 for m in flagged if m.crack_m is not None]
    _compared_marks(axes, flagged, days, cracks, x)
    (rings,) = axes.plot(
        days,
        cracks,
        linestyle="none",
        marker="o",
        markersize=15,
        markerfacecolor="none",
        markeredgecolor=_CRITICAL,
        markeredgewidth=2,
        label="flagged: far from the forecast",
    )
    rings.set_gid("inspections-flagged")
    for day, crack, mark in zip(days, cracks, flagged, strict=True):
        said = f"flagged z={mark.flagged_z:+.1f}"
        if mark.compared is not None:
            said += f" vs {fmt.mm(mark.compared.crack_m)} mm ({fmt.date(mark.compared.at)})"
        label = axes.annotate(
            said,
            (day, crack),
            xytext=(10, 8),
            textcoords="offset points",
            color=_CRITICAL,
            fontsize=8,
            bbox={"boxstyle": "round,pad=0.2", "facecolor": "white", "edgecolor": "none"},
        )
        label.set_gid("flagged-label")


def _compared_marks(
    axes: Axes,
    flagged: Sequence[InspectionMark],
    days: Any,
    cracks: Sequence[float],
    x: TailAxis,
) -> None:
    """Each flagged finding's comparison: a red diamond at the estimate it was compared with,
    a dotted line from there to the finding."""
    pairs = [(m, d, c) for m, d, c in zip(flagged, days, cracks, strict=True) if m.compared]
    if not pairs:
        return
    at = [float(x.of([m.compared.at], [m.compared.flights])[0]) for m, _, _ in pairs if m.compared]
    compared = [m.compared.crack_m * 1000 for m, _, _ in pairs if m.compared]
    for start, estimate, (_, day, crack) in zip(at, compared, pairs, strict=True):
        (link,) = axes.plot([start, day], [estimate, crack], color=_CRITICAL, linestyle=":")
        link.set_gid("flagged-link")
    (diamonds,) = axes.plot(
        at,
        compared,
        linestyle="none",
        marker="D",
        markersize=6,
        markerfacecolor="none",
        markeredgecolor=_CRITICAL,
        label="flagged: the estimate it was compared with",
    )
    diamonds.set_gid("flagged-compared")


def _tail_figure(
    series: Series,
    critical_crack_m: float,
    inspections: Sequence[InspectionMark],
    *,
    inspect_by: datetime | None,
    history: HistoryCurve | None,
    as_of: datetime | None,
    location: str | None = None,
    axis: ChartAxis = "date",
) -> Figure:
    """The tail's estimated crack over its recorded flights (history), then from its last
    recorded flight over the horizon, with its band, a_crit, its inspections (measured: dots,
    nothing found: open triangles at the detection limit, repairs: crosses), the as-of date
    and the inspect-by date; against dates or flights flown (axis)."""
    figure = _figure(4.6)
    title = "estimated crack and forecast" if history else "forecast crack"
    where = series.tail if location is None else f"{series.tail} at {location}"
    recorded = (history.dates, history.flights) if history is not None else ((), ())
    x = TailAxis(axis, ([*recorded[0], *series.dates], [*recorded[1], *series.flights]))
    axes = _axes(figure, f"{where}: {title} with p05–p95 band", x)
    if history is not None and len(history.dates):
        (past,) = axes.plot(
            x.of(history.dates, history.flights),
            _mm(history.crack_m),
            color="#4a5568",
            linewidth=1.4,
            label="estimated over recorded flights",
        )
        past.set_gid("history")
    # A band a few tenths of a mm wide on a 50 mm axis vanished at a light fill: a stronger fill
    # and its edges drawn keep it visible at any width.
    ahead = x.of(series.dates, series.flights)
    band = axes.fill_between(
        ahead,
        _mm(series.p05),
        _mm(series.p95),
        color=_BAND,
        alpha=0.45,
        linewidth=0,
        label="p05–p95 band",
    )
    band.set_gid("band")
    for name, values in (("p05", series.p05), ("p95", series.p95)):
        (edge,) = axes.plot(ahead, _mm(values), color=_BAND_EDGE, linewidth=0.9, linestyle="--")
        edge.set_gid(f"band-{name}")
    (line,) = axes.plot(ahead, _mm(series.crack_m), color=_INK, linewidth=1.8, label="forecast")
    line.set_gid("forecast")
    _critical_line(axes, critical_crack_m)
    styles = {
        "measured": {"marker": "o", "color": "#2f855a", "label": "inspection: measured"},
        "not-found": {
            "marker": "v",
            "color": "#718096",
            "label": "inspection: nothing found (below limit)",
            "markerfacecolor": "none",
        },
        "repair": {"marker": "X", "color": "#b7791f", "label": "repair"},
    }
    for kind, style in styles.items():
        marks = [m for m in inspections if m.kind == kind and m.crack_m is not None]
        if not marks:
            continue
        (points,) = axes.plot(
            x.of([m.inspected_at for m in marks], [m.flights for m in marks]),
            [m.crack_m * 1000 for m in marks if m.crack_m is not None],
            linestyle="none",
            markersize=7,
            **style,  # type: ignore[arg-type]
        )
        points.set_gid(f"inspections-{kind}")
    _flagged_marks(axes, inspections, x)
    if inspect_by is not None:
        due = axes.axvline(
            x.at(inspect_by),
            color="#dd6b20",
            linestyle=":",
            linewidth=1.4,
            label="inspect by",
        )
        due.set_gid("inspect-by")
    if as_of is not None:
        today = axes.axvline(
            x.at(as_of),
            color="#2b6cb0",
            linestyle="-.",
            linewidth=1.1,
            label=f"as of {fmt.date(as_of)}",
        )
        today.set_gid("as-of")
    _clip_at_critical(axes, critical_crack_m)
    axes.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncols=4, fontsize=8, frameon=False)
    return figure


# how far above a_crit a chart shows: beyond it a band measures nothing (a march holds a crack
# past a_crit at a bound), and a p95 there put the axis at tens of metres, the data a flat line
CLIP_FRACTION = 1.5


def _clip_at_critical(axes: Axes, critical_crack_m: float) -> None:
    """The y axis from 0 to at most CLIP_FRACTION a_crit, saying "past critical" where the
    drawn band or crack runs beyond it."""
    top_mm = CLIP_FRACTION * critical_crack_m * 1000
    _, drawn_top = axes.get_ylim()
    if drawn_top <= top_mm:
        axes.set_ylim(bottom=0)
        return
    axes.set_ylim(0, top_mm)
    note = axes.text(
        0.01,
        0.97,
        f"past critical: clipped at {fmt.mm(top_mm / 1000)} mm ({CLIP_FRACTION:g} a_crit)",
        transform=axes.transAxes,
        color=_CRITICAL,
        fontsize=8,
        va="top",
    )
    note.set_gid("clipped")


def _ranking_figure(series: Sequence[Series], critical_crack_m: float) -> Figure:
    """The p50 crack and p05-p95 band of each of the most at-risk tails against a_crit."""
    figure = _figure(4.8)
    axes = _axes(figure, f"Top {len(series)} tails by risk: p50 crack with p05–p95 band")
    for i, s in enumerate(series):
        colour = _PALETTE[i % len(_PALETTE)]
        band = axes.fill_between(
            _days(s.dates), _mm(s.p05), _mm(s.p95), color=colour, alpha=0.12, linewidth=0
        )
        band.set_gid(f"band-{i + 1}")
        (line,) = axes.plot(
            _days(s.dates),
            _mm(s.p50),
            color=colour,
            linewidth=1.5,
            label=f"{s.tail}  P(crit) {fmt.percent(s.prob_critical)}",
        )
        line.set_gid(f"tail-{i + 1}")
    _critical_line(axes, critical_crack_m)
    axes.set_ylim(bottom=0)
    axes.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8, frameon=False)
    return figure


def tail_chart(
    series: Series,
    critical_crack_m: float,
    inspections: Sequence[InspectionMark],
    *,
    inspect_by: datetime | None,
    image_format: ImageFormat,
    history: HistoryCurve | None = None,
    as_of: datetime | None = None,
    location: str | None = None,
    axis: ChartAxis = "date",
) -> bytes:
    """One tail's chart (see _tail_figure) as SVG or PNG; location: named in the title (None:
    the default one, a one-location fleet's); axis: dates, or flights flown (a test's blocks
    of cycles)."""
    return _draw(
        lambda: _tail_figure(
            series,
            critical_crack_m,
            inspections,
            inspect_by=inspect_by,
            history=history,
            as_of=as_of,
            location=location,
            axis=axis,
        ),
        image_format,
    )


def ranking_chart(
    series: Sequence[Series], critical_crack_m: float, *, image_format: ImageFormat
) -> bytes:
    """The most at-risk tails' chart (see _ranking_figure) as SVG or PNG."""
    return _draw(lambda: _ranking_figure(series, critical_crack_m), image_format)


def _draw(build: Callable[[], Figure], image_format: ImageFormat) -> bytes:
    """Build and save a figure: SVG (text as text, no timestamp) or PNG (150 dpi).

    matplotlib's style (rc_context) and caches are global: one chart at a time."""
    import matplotlib

    matplotlib.use("Agg")  # no pyplot, no display: the file back ends alone
    if image_format not in MEDIA_TYPES:
        raise ValueError(f"image_format must be one of {tuple(MEDIA_TYPES)}, got {image_format!r}")
    buffer = io.BytesIO()
    with _render_lock, matplotlib.rc_context(_STYLE):
        figure = build()
        if image_format == "svg":
            figure.savefig(buffer, format="svg", metadata={"Date": None})
        else:
            figure.savefig(buffer, format="png", dpi=150)
    return buffer.getvalue()


def inline_svg(svg: bytes) -> str:
    """An SVG document's <svg> element alone, for embedding in a page (no prolog, no doctype)."""
    text = svg.decode()
    return text[text.index("<svg") :]
