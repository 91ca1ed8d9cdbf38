"""Server-side charts: deterministic SVG, the style held while threads draw at once."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest

from app.web import charts
from app.web.chart_axis import ChartAxis

START = datetime(2025, 1, 1, tzinfo=UTC)


def _series(tail: str, growth: float) -> charts.Series:
    dates = [START + timedelta(days=d) for d in range(31)]
    crack = [0.01 + growth * d for d in range(31)]
    return charts.Series(
        tail=tail,
        dates=dates,
        crack_m=crack,
        p05=[c * 0.95 for c in crack],
        p50=crack,
        p95=[c * 1.05 for c in crack[:-1]] + [None],  # a diverged last sample: a gap, no error
        prob_critical=0.25,
    )


def _tail_svg() -> bytes:
    marks = [
        charts.InspectionMark(START - timedelta(days=3), "measured", 0.0098),
        charts.InspectionMark(START - timedelta(days=2), "not-found", 0.002),
        charts.InspectionMark(START - timedelta(days=1), "repair", 0.004),
    ]
    return charts.tail_chart(
        _series("N1", 2e-4), 0.05, marks, inspect_by=START + timedelta(days=10), image_format="svg"
    )


def test_tail_chart_holds_every_element() -> None:
    svg = _tail_svg().decode()
    for gid in (
        "band",
        "forecast",
        "a-crit",
        "inspect-by",
        "inspections-measured",
        "inspections-not-found",
        "inspections-repair",
    ):
        assert f'id="{gid}"' in svg
    assert "a_crit 50.00 mm" in svg  # text kept as text
    assert "2025-01-15" in svg or "2025-01-13" in svg  # ISO dates on the axis


def test_svg_is_deterministic_while_threads_draw_together() -> None:
    reference = _tail_svg()
    ranking = [_series(f"N{i}", 1e-4 * i) for i in range(1, 4)]
    with ThreadPoolExecutor(4) as pool:
        tails = [pool.submit(_tail_svg) for _ in range(4)]
        others = [
            pool.submit(charts.ranking_chart, ranking, 0.05, image_format="png") for _ in range(4)
        ]
        assert all(t.result() == reference for t in tails)
        assert all(o.result().startswith(b"\x89PNG") for o in others)


def test_unknown_format_is_rejected() -> None:
    with pytest.raises(ValueError, match="image_format must be one of"):
        charts.ranking_chart([], 0.05, image_format="gif")  # type: ignore[arg-type]


def test_inline_svg_drops_the_prolog() -> None:
    assert charts.inline_svg(_tail_svg()).startswith("<svg")


def test_a_band_past_critical_is_clipped_at_one_and_a_half_a_crit_and_says_so() -> None:
    """A p95 of metres put the axis at tens of thousands of mm: the chart stops at 1.5 a_crit."""
    exploding = charts.Series(
        tail="N1",
        dates=[START + timedelta(days=d) for d in range(31)],
        crack_m=[0.01 + 1e-4 * d for d in range(31)],
        p05=[0.01] * 31,
        p50=[0.01 + 1e-4 * d for d in range(31)],
        p95=[0.01 * 1.5**d for d in range(31)],  # to ~1900 m
        prob_critical=0.4,
    )
    figure = charts._tail_figure(
        exploding, 0.04, [], inspect_by=None, history=None, as_of=None, location="wing"
    )
    (axes,) = figure.axes
    assert axes.get_ylim() == (0.0, pytest.approx(60.0))  # mm: 1.5 x 40 mm
    assert axes.get_title(loc="left").startswith("N1 at wing: ")
    svg = charts.tail_chart(
        exploding, 0.04, [], inspect_by=None, image_format="svg", location="wing"
    ).decode()
    assert 'id="clipped"' in svg and "past critical: clipped at 60.00 mm" in svg
    calm = charts._tail_figure(
        _series("N2", 1e-4), 0.05, [], inspect_by=None, history=None, as_of=None
    )
    top = calm.axes[0].get_ylim()[1]
    assert 0.05 * 1000 < top < 1.5 * 0.05 * 1000  # a_crit in view, nothing clipped
    assert calm.axes[0].get_title(loc="left").startswith("N2: ")


def _flagged_chart(axis: ChartAxis) -> tuple[Any, charts.InspectionMark]:
    """A tail of one flight a day for 100 days from 2024-10-01 (flights 1..100), forecast from
    flight 100 on 2025-01-01; an inspection after 40 flights flagged against 7 mm then."""
    flown = [START - timedelta(days=100 - k) for k in range(1, 101)]
    history = charts.HistoryCurve(flown, [0.005 + 5e-5 * k for k in range(100)], range(1, 101))
    compared = charts.Compared(0.007, flown[39], 40)
    mark = charts.InspectionMark(
        flown[39] + timedelta(hours=12), "measured", 0.0123, 5.2, 40, compared
    )
    series = _series("N1", 2e-4)
    series = charts.Series(**{**series.__dict__, "flights": list(range(100, 131))})
    figure = charts._tail_figure(
        series, 0.05, [mark], inspect_by=None, history=history, as_of=START, axis=axis
    )
    return figure, mark


def test_a_flagged_inspection_is_drawn_against_what_it_was_compared_with() -> None:
    """Not today's projection: the estimate after its last recorded flight, 60 days before the
    forecast starts, a diamond there, a dotted line to the finding, and the label says so."""
    figure, mark = _flagged_chart("date")
    (axes,) = figure.axes
    lines = {line.get_gid(): line for line in axes.get_lines()}
    diamond = lines["flagged-compared"]
    assert mark.compared is not None
    assert list(diamond.get_xdata()) == pytest.approx(list(charts._days([mark.compared.at])))
    assert list(diamond.get_ydata()) == pytest.approx([7.0])  # mm
    link = lines["flagged-link"]
    assert list(link.get_ydata()) == pytest.approx([7.0, 12.3])
    (label,) = [t for t in axes.texts if t.get_gid() == "flagged-label"]
    assert label.get_text() == "flagged z=+5.2 vs 7.00 mm (2024-11-02)"
    assert diamond.get_label() == "flagged: the estimate it was compared with"


def test_the_flights_axis_counts_flights_flown() -> None:
    """axis='flights': history after flights 1..100, the forecast from flight 100, the
    inspection after the 40 flights flown before it, the as-of date at the forecast's flight."""
    figure, _ = _flagged_chart("flights")
    (axes,) = figure.axes
    lines = {line.get_gid(): line for line in axes.get_lines()}
    assert list(lines["history"].get_xdata()) == list(range(1, 101))
    assert list(lines["forecast"].get_xdata())[:2] == [100, 101]
    assert list(lines["inspections-measured"].get_xdata()) == [40]
    assert list(lines["flagged-compared"].get_xdata()) == [40]
    assert list(lines["as-of"].get_xdata()) == [100, 100]  # START: the forecast's first day
    assert axes.get_xlabel().startswith("flights flown")
    with pytest.raises(ValueError, match="axis must be one of"):
        charts._tail_figure(
            _series("N1", 2e-4),
            0.05,
            [],
            inspect_by=None,
            history=None,
            as_of=None,
            axis="cycles",  # type: ignore[arg-type]
        )
