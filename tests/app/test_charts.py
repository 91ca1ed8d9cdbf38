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
