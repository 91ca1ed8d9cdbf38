import numpy as np
import pytest

from app.services.retrain import holdout_split


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
