import math

import numpy as np
import pytest
import torch

from model import forecast as fc
from model.cells import InputBox
from model.hybrid import CrackGrowthModel, ModelSpec
from model.physics import ParisLaw, paris_closed_form

LAW = ParisLaw()


def _physics() -> CrackGrowthModel:
    return CrackGrowthModel(ModelSpec(kernel="physics", law=LAW))


def _euler_until(crack: float, stresses: np.ndarray, critical: float) -> int:
    n = 0
    while crack < critical:
        stress = stresses[n % len(stresses)]
        crack += LAW.c * (stress * math.sqrt(math.pi * crack)) ** LAW.m
        n += 1
    return n


def test_utilization_over_the_window_and_over_a_short_history() -> None:
    day = fc.NS_PER_DAY
    times = np.arange(0, 200 * day, day // 4)  # 4 a day for 200 days
    stress = np.arange(len(times), dtype=float)
    usage = fc.recent_utilization(times, stress, window_days=90)
    assert usage.flights_per_day == pytest.approx(4.0)
    assert len(usage.recent_stress_mpa) == 360
    assert usage.recent_stress_mpa[-1] == stress[-1]
    short = fc.recent_utilization(times[:9], stress[:9], window_days=90)  # 9 flights in 2 days
    assert short.flights_per_day == pytest.approx(4.5)
    single = fc.recent_utilization(times[:1], stress[:1], window_days=90)
    assert single.flights_per_day == 1.0
    with pytest.raises(ValueError, match="at least one"):
        fc.recent_utilization(times[:0], stress[:0], 90)


def test_loads_come_from_the_load_window_and_the_rate_from_the_utilization_window() -> None:
    """A year of loads (a heavy-tailed damage needs a long sample) at the last 90 days' rate
    (a change of route shows within weeks)."""
    day = fc.NS_PER_DAY
    slow = np.arange(0, 300 * day, day // 2)  # 2 a day for 300 days
    fast = 300 * day + np.arange(0, 100 * day, day // 4)  # then 4 a day for 100 days
    times = np.concatenate([slow, fast])
    stress = np.arange(len(times), dtype=float)
    usage = fc.recent_utilization(times, stress, window_days=90, load_window_days=365)
    assert usage.flights_per_day == pytest.approx(4.0)
    in_year = times > times[-1] - 365 * day
    np.testing.assert_array_equal(usage.recent_stress_mpa, stress[in_year])
    assert len(usage.recent_stress_mpa) == 265 * 2 + 400
    # a load window shorter than the rate's is the rate's
    short = fc.recent_utilization(times, stress, window_days=90, load_window_days=30)
    assert len(short.recent_stress_mpa) == 360


def test_project_loads_cycles_in_order_from_a_phase() -> None:
    recent = np.array([1.0, 2.0, 3.0])
    assert fc.project_loads(recent, 7).tolist() == [1, 2, 3, 1, 2, 3, 1]
    assert fc.project_loads(recent, 4, start=2).tolist() == [3, 1, 2, 3]
    with pytest.raises(ValueError, match="empty"):
        fc.project_loads(np.array([]), 3)


def test_march_ahead_follows_the_paris_closed_form() -> None:
    # Euler with one step per cycle converges to the closed form while da/a stays small.
    crack = torch.tensor([0.005], dtype=torch.float64)
    trajectory = fc.march_ahead(_physics(), crack, torch.full((1, 20_000), 100.0))
    exact = paris_closed_form(0.005, 100.0, 20_000.0, LAW)
    assert float(trajectory[0, -1]) == pytest.approx(float(exact), rel=2e-3)


def test_flights_to_critical_matches_a_reference_march_across_chunks() -> None:
    cycles = [np.array([150.0]), np.array([120.0, 220.0, 90.0]), np.array([100.0])]
    now = [0.01, 0.005, 0.06]
    caps = [10**6, 10**6, 10]
    answer = fc.flights_to_critical(_physics(), now, cycles, 0.05, caps, chunk_flights=500)
    assert answer[0] == _euler_until(0.01, cycles[0], 0.05)
    assert answer[1] == _euler_until(0.005, cycles[1], 0.05)
    assert answer[2] == 0  # already past critical


def test_flights_to_critical_is_none_beyond_the_cap() -> None:
    needed = _euler_until(0.01, np.array([150.0]), 0.05)
    model = _physics()
    assert fc.flights_to_critical(model, [0.01], [np.array([150.0])], 0.05, [needed - 1]) == [None]
    assert fc.flights_to_critical(model, [0.01], [np.array([150.0])], 0.05, [needed]) == [needed]


def test_flights_to_critical_with_a_learned_kernel_runs_batched() -> None:
    box = InputBox((90.0, 130.0), (LAW.initial_crack_m, LAW.critical_crack_m))
    model = CrackGrowthModel(ModelSpec(kernel="residual", law=LAW, box=box))
    # The residual kernel starts as the physics: same answer as the reference march.
    answer = fc.flights_to_critical(model, [0.02, 0.03], [np.array([130.0])] * 2, 0.05, [10**6] * 2)
    assert answer == [
        _euler_until(0.02, np.array([130.0]), 0.05),
        _euler_until(0.03, np.array([130.0]), 0.05),
    ]


def test_daily_points_stop_at_the_first_critical_point() -> None:
    trajectory = np.linspace(0.01, 0.06, 101)  # crosses 0.05 at flight 80
    days, flights = fc.daily_points(trajectory, 4.0, 30, 0.05)
    assert flights[-1] == 80 and days[-1] == 20
    days, flights = fc.daily_points(trajectory[:41], 4.0, 10, 0.05)
    assert days.tolist() == list(range(11)) and flights[-1] == 40
    assert fc.flights_within(10, 4.0) == 40
    assert fc.date_after_flights(0, 2, 4.0) == fc.NS_PER_DAY // 2
