"""Server-side charts: deterministic SVG, the style held while threads draw at once."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from datetime import UTC, datetime, timedelta

import pytest

from app.web import charts

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
