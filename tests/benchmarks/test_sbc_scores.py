"""benchmarks/sbc_scores.py's fleet-clustered chi-square: it equals the plain one for tails that
are independent, forgives fleets whose tails fall together, and still rejects a shared bias."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.sbc_scores import PIT_SHARES, clustered_pit_p, design_effect, pit_p, scores


def _fleets(rng: np.random.Generator, fleets: int, tails: int, shares: np.ndarray) -> np.ndarray:
    return rng.multinomial(tails, shares, size=fleets)


def test_independent_tails_have_no_design_effect() -> None:
    rng = np.random.default_rng(0)
    effects = [design_effect(_fleets(rng, 50, 60, PIT_SHARES)) for _ in range(40)]
    assert np.mean(effects) == pytest.approx(1.0, abs=0.1)


def test_fleets_whose_tails_fall_together_are_forgiven() -> None:
    """Each fleet's 30 tails land in one bin, drawn from the null shares: the plain chi-square
    rejects most such sets of 60 fleets; the clustered one about as often as its level."""
    rng = np.random.default_rng(1)
    plain, clustered, effects = [], [], []
    for _ in range(40):
        by_fleet = 30 * _fleets(rng, 60, 1, PIT_SHARES)
        plain.append(pit_p(by_fleet.sum(axis=0)) < 0.01)
        clustered.append(clustered_pit_p(by_fleet) < 0.01)
        effects.append(design_effect(by_fleet))
    assert np.mean(plain) > 0.7
    assert np.mean(clustered) <= 0.1
    assert np.median(effects) == pytest.approx(30, rel=0.3)


def test_a_bias_every_fleet_shares_is_still_rejected() -> None:
    rng = np.random.default_rng(2)
    biased = np.array([0.05, 0.35, 0.50, 0.10])
    assert all(clustered_pit_p(_fleets(rng, 50, 60, biased)) < 1e-3 for _ in range(10))


def test_scores_pool_each_group_and_score_it_by_fleet() -> None:
    """Two fleets of four tails: the pooled bins are the tails' own; a group whose tails all
    lie in one fleet has no between-fleet spread to correct by."""
    q = [[1.0, 2.0, 3.0]] * 4
    fleet = {
        "critical_m": 10.0,
        "q_m": q,
        "prob_critical": [0.0] * 4,
        "z_rank": [0.5] * 4,
        "draw": {},
        "fit_s": 1.0,
    }
    results = [
        fleet
        | {"truth_m": [0.5, 1.5, 2.5, 3.5], "inspected": [1, 1, 0, 0], "beyond": [0, 0, 0, 0]},
        fleet
        | {"truth_m": [2.5, 2.5, 2.5, 9.0], "inspected": [1, 1, 1, 1], "beyond": [0, 0, 0, 1]},
    ]
    out = scores(results)
    assert out["inspected"]["pit_bins"] == [1, 1, 3, 1]
    assert out["uninspected"]["pit_bins"] == [0, 0, 1, 1]
    assert out["beyond"]["pit_bins"] == [0, 0, 0, 1]
    assert np.isfinite(out["inspected"]["pit_p_fleets"])
    # the group's tails all in one fleet: no spread between fleets to measure
    assert np.isnan(out["uninspected"]["pit_p_fleets"])
    assert np.isnan(out["beyond"]["pit_p_fleets"])


def test_a_group_chosen_by_its_outcome_fails_a_calibrated_forecast() -> None:
    """Why benchmarks/sbc.py chooses "beyond" by the forecast: every truth drawn from its own
    calibrated forecast N(mean, 1), 50 fleets of 60 tails; the tails whose forecast median lies
    past a threshold sit in their bins at the null shares, those whose truth does read low."""
    rng = np.random.default_rng(3)
    fleets = []
    for _ in range(50):
        mean = rng.normal(0.0, 1.0, 60)
        truth = mean + rng.normal(0.0, 1.0, 60)
        q = np.stack([mean - 1.6449, mean, mean + 1.6449], axis=1)
        fleets.append(
            {
                "truth_m": truth.tolist(),
                "q_m": q.tolist(),
                "critical_m": 1e9,
                "prob_critical": [0.0] * 60,
                "z_rank": [0.5] * 60,
                "inspected": [1] * 60,
                "beyond": (mean > 1.0).tolist(),
                "beyond_truth": (truth > 1.0).tolist(),
            }
        )
    out = scores(fleets)
    assert out["beyond"]["pit_p_fleets"] > 0.01
    assert out["beyond_truth"]["pit_p_fleets"] < 1e-6
    shares = np.asarray(out["beyond_truth"]["pit_bins"]) / out["beyond_truth"]["tails"]
    assert shares[2:].sum() > 0.7  # above the median: the tails that grew more than forecast
