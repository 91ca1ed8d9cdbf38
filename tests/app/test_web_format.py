"""Numbers as the pages show them."""

from __future__ import annotations

from datetime import UTC, datetime

import pytest

from app.web import format as fmt


@pytest.mark.parametrize(
    ("metres", "shown"),
    [(0.012345, "12.35"), (0.05, "50.00"), (0.0050049, "5.00"), (None, "—")],
)
def test_mm(metres: float | None, shown: str) -> None:
    assert fmt.mm(metres) == shown


def test_a_crack_past_a_crit_says_so() -> None:
    assert fmt.crack_mm(0.0123, 0.05) == "12.30"
    assert fmt.crack_mm(0.05, 0.05) == fmt.crack_mm(4.2, 0.05) == "> a_crit"
    assert fmt.crack_mm(None, 0.05) == "> a_crit"  # a sampled march that diverged
    assert fmt.crack_band(0.0119, 0.0128, 0.05) == "11.90–12.80"
    assert fmt.crack_band(0.0419, None, 0.05) == "41.90–> a_crit"
    assert fmt.crack_band(0.051, None, 0.05) == ""


@pytest.mark.parametrize(
    ("probability", "shown"),
    [
        (0.0, "0 %"),
        (0.0004, "<0.1 %"),
        (0.001, "0.1 %"),
        (0.1234, "12.3 %"),
        (0.9994, ">99.9 %"),
        (1.0, "100 %"),
        (None, "—"),
    ],
)
def test_percent_keeps_the_ends_exact(probability: float | None, shown: str) -> None:
    assert fmt.percent(probability) == shown


def test_dates_are_iso_utc() -> None:
    moment = datetime(2026, 3, 14, 9, 30, 59, tzinfo=UTC)
    assert fmt.date(moment) == "2026-03-14"
    assert fmt.timestamp(moment) == "2026-03-14 09:30Z"
    assert fmt.date(None) == "—"


def test_counts_and_numbers() -> None:
    assert fmt.count(7300) == "7,300"
    assert fmt.number(147.84, 1) == "147.8"
    assert fmt.number(None) == "—"


def test_a_culprit_of_the_promotion_gate_in_one_line() -> None:
    entry = {"error_pct": 152.25, "tail": "T3", "inspection_id": "I-7", "z": 4.0}
    assert fmt.culprit(entry) == "T3 I-7: error_pct 152.2, z 4"
    assert fmt.culprit({"tail": "T3"}) == "T3"
    assert fmt.culprit({"error_pct": 1.5}) == "error_pct 1.5"
    assert fmt.culprit("T4 I-9") == "T4 I-9"


def test_a_residual_strength_with_its_margin_in_one_line() -> None:
    assert fmt.signed_percent(0.993) == "+99.3 %"
    assert fmt.signed_percent(-0.04) == "\u22124.0 %"
    assert fmt.signed_percent(None) == "—"
    assert fmt.criterion_words("net_section_yield") == "net-section yield"
    words = fmt.strength_words(299.04, "net_section_yield", 0.9936, 150.0)
    assert words == "299 MPa (net-section yield), margin +99.4 % on the limit 150 MPa"
    below = fmt.strength_words(0.0, "extent", -1.0, 150.0)
    assert below == "0 MPa (section severed), margin \u2212100.0 % on the limit 150 MPa"
    # a table's cell (the fleet page's and the client's ranking)
    assert fmt.strength_margin(299.04, 0.9936) == "299 MPa, +99.4 %"
    assert fmt.strength_margin(120.4, -0.197) == "120 MPa, \u221219.7 %"
    assert fmt.strength_margin(None, None) == "—"
