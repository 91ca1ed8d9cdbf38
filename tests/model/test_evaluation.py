import numpy as np
import pytest
import torch

from model.evaluation import abs_percent_errors, holdout_split, select_rows
from model.hybrid import CrackGrowthModel, ModelSpec
from model.integrate import LoadHistory, Observations


@pytest.mark.parametrize(
    ("tails", "fraction", "held_out"),
    [(1, 0.2, 0), (2, 0.2, 0), (3, 0.2, 1), (5, 0.2, 1), (15, 0.2, 3), (15, 0.0, 0), (3, 0.99, 2)],
)
def test_holdout_sizes(tails: int, fraction: float, held_out: int) -> None:
    train, validation = holdout_split(tails, fraction, seed=0)
    assert len(validation) == held_out
    assert sorted(np.concatenate((train, validation)).tolist()) == list(range(tails))


def test_holdout_is_deterministic_for_a_seed() -> None:
    assert holdout_split(15, 0.2, 7)[1].tolist() == holdout_split(15, 0.2, 7)[1].tolist()
    assert holdout_split(15, 0.2, 7)[1].tolist() != holdout_split(15, 0.2, 8)[1].tolist()


@pytest.mark.parametrize(
    ("tails", "fraction", "name"), [(-1, 0.2, "n_tails"), (5, 1.0, "fraction")]
)
def test_holdout_rejects_bad_arguments(tails: int, fraction: float, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        holdout_split(tails, fraction, seed=0)


def _physics_case() -> tuple[CrackGrowthModel, LoadHistory, torch.Tensor]:
    model = CrackGrowthModel(ModelSpec(kernel="physics"))
    loads = LoadHistory(torch.full((3, 50), 120.0, dtype=torch.float64), torch.tensor([50, 40, 30]))
    with torch.no_grad():
        trajectory = model.trajectory(loads)  # (aircraft, flights + 1)
    return model, loads, trajectory


def test_abs_percent_errors_leave_non_detections_out() -> None:
    model, loads, trajectory = _physics_case()
    truth = trajectory[torch.arange(3), torch.tensor([50, 40, 30])]
    measured = torch.stack([truth[0] * 1.10, truth[1] * 0.95, torch.tensor(float("nan"))])
    observations = Observations(
        torch.tensor([0, 1, 2]),
        torch.tensor([50, 40, 30]),
        measured,
        detected=torch.tensor([True, True, False]),
        detection_a50_m=torch.tensor([0.001, 0.001, 0.001]),
    )
    errors = abs_percent_errors(model, loads, observations)
    assert errors["count"] == 2
    # |1/1.10 - 1| = 9.09 %, |1/0.95 - 1| = 5.26 %
    assert errors["max_abs_pct_error"] == pytest.approx(100 * (1 - 1 / 1.10), rel=1e-9)
    assert errors["median_abs_pct_error"] == pytest.approx(
        50 * ((1 - 1 / 1.10) + (1 / 0.95 - 1)), rel=1e-9
    )
    assert all(np.isfinite(float(v)) for v in errors.values())


def test_abs_percent_errors_without_a_measurement_count_zero() -> None:
    model, loads, _ = _physics_case()
    missed = Observations(
        torch.tensor([0]),
        torch.tensor([10]),
        torch.tensor([float("nan")]),
        detected=torch.tensor([False]),
        detection_a50_m=torch.tensor([0.001]),
    )
    assert abs_percent_errors(model, loads, missed) == {"count": 0}


def test_select_rows_reindexes_loads_and_observations() -> None:
    _, loads, _ = _physics_case()
    observations = Observations(
        torch.tensor([0, 1, 2, 2]),
        torch.tensor([5, 6, 7, 8]),
        torch.tensor([0.01, 0.02, 0.03, 0.04], dtype=torch.float64),
    )
    rows_loads, rows_obs = select_rows(loads, observations, np.array([2, 0]))
    assert rows_loads.lengths.tolist() == [30, 50]
    assert rows_obs.aircraft.tolist() == [1, 0, 0]
    assert rows_obs.flights.tolist() == [5, 7, 8]
    assert rows_obs.crack_length_m.tolist() == [0.01, 0.03, 0.04]
