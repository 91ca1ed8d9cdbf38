"""The batched monotone cubic against scipy's PchipInterpolator, row by row: the same bits."""

import numpy as np
import pytest
from scipy.interpolate import PchipInterpolator

from model.monotone_cubic import pchip_rows


@pytest.mark.parametrize("knots", [2, 3, 12])
def test_each_row_is_scipys_pchip_bit_for_bit(knots: int) -> None:
    """Rows with flat runs, sign changes and uneven knots, read at points that include the
    span's ends and knots themselves."""
    rng = np.random.default_rng(knots)
    x = np.sort(rng.uniform(-3.0, 3.0, (40, knots)), axis=1)
    y = np.round(rng.normal(size=(40, knots)), 1)
    y[:, 1 : knots // 2 + 1] = 1.0  # flats
    at = np.concatenate([np.linspace(x[:, 0].max(), x[:, -1].min(), 301), x[0, 1:-1]])
    at = at[(at >= x[:, 0].max()) & (at <= x[:, -1].min())]
    expected = np.stack([PchipInterpolator(a, b)(at) for a, b in zip(x, y, strict=True)])
    assert np.array_equal(pchip_rows(x, y, at), expected)


def test_rows_of_unlike_shapes_are_refused() -> None:
    with pytest.raises(ValueError, match="rows, knots"):
        pchip_rows(np.zeros((3, 4)), np.zeros((3, 5)), np.zeros(2))
