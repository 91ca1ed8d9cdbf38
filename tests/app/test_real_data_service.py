"""benchmarks/real_data_service.py's protocol and scoring, without a server (the benchmark itself
runs the service): each inspection observes exactly the flights up to its cycle count, and the
band's coverage and misses are counted as real_data.score() counts them."""

from __future__ import annotations

import io

import numpy as np
import pandas as pd
import pytest

from benchmarks.real_data_service import _flights_csv, _inspections, _score


def test_an_inspection_observes_the_flights_up_to_its_cycle_count() -> None:
    flights = pd.read_csv(io.BytesIO(_flights_csv(["A-01"], 300)), parse_dates=["flown_at"])
    early = pd.DataFrame({"specimen": ["A-01"] * 3, "cycles": [10_000, 20_000, 30_000]})
    early["crack_m"] = [0.024, 0.025, 0.027]
    for inspection, cycles in zip(_inspections(early, 100), early["cycles"], strict=True):
        at = pd.Timestamp(inspection["inspected_at"])
        assert (flights["flown_at"] < at).sum() * 100 == cycles
    assert flights["flown_at"].diff().dropna().eq(pd.Timedelta(days=1)).all()  # one a day


def test_scores_count_misses_above_p95_and_bands_past_critical() -> None:
    """A band past a_crit (the service's null p95, read as unbounded) holds what lies above
    its p05."""
    ours = pd.DataFrame(
        {
            "crack_m": [1.0, 1.0, 1.0, 1.0],
            "p05": [0.9, 0.9, 0.5, 0.95],
            "p50": [1.0, 1.1, 0.8, 0.95],
            "p95": [1.1, 1.2, 0.95, np.inf],
        }
    )
    risk = pd.DataFrame(
        {"prob_critical": [0.7, 0.2], "life": [90.0, 130.0], "life_p05": [80.0, 110.0]},
        index=["A-01", "A-02"],
    ).assign(life_p95=[120.0, 150.0])
    lives = pd.Series({"A-01": 100.0, "A-02": 100.0})
    scores = _score(ours, risk, lives, "fitted")
    assert scores.coverage == 75.0 and scores.above == 25.0 and scores.missing == 1
    assert scores.flagged == 1 and scores.lives_held == 1 and scores.lives == 2
    assert np.allclose(scores.life, (20.0, 30.0))
    assert scores.cracks[1] == pytest.approx(20.0)  # the p50 of 0.8 against 1.0
