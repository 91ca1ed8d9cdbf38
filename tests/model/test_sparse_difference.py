"""The sparse forward-difference Jacobian against scipy's own from `jac_sparsity`: the same
matrix and the same fit, bit for bit."""

import numpy as np
from scipy.optimize import least_squares
from scipy.optimize._numdiff import approx_derivative
from scipy.sparse import lil_matrix

from model.sparse_difference import SparseDifference


def _problem(seed: int):
    """Residuals of 3 shared parameters and one per group of rows (a tail's own factor): the
    shape of the measured cracks' trend (model.geometry_trend), some rows with no own one."""
    rng = np.random.default_rng(seed)
    rows, own_count = 90, 20
    own = rng.integers(-1, own_count, rows)
    t = rng.uniform(0.1, 2.0, rows)
    data = 0.3 + 0.8 * t - 0.4 * t**2 + rng.normal(0.0, 0.05, rows)

    def fun(theta: np.ndarray) -> np.ndarray:
        shift = np.append(theta[3:], 0.0)[own]
        return data - (np.exp(theta[0] + shift) + theta[1] * t + theta[2] * t**2)

    sparsity = lil_matrix((rows, 3 + own_count), dtype=np.int8)
    sparsity[:, :3] = 1
    tailed = np.flatnonzero(own >= 0)
    sparsity[tailed, 3 + own[tailed]] = 1
    start = np.zeros(3 + own_count)
    start[3::2] = 0.1
    return fun, sparsity, start


def test_the_jacobian_is_scipys_bit_for_bit() -> None:
    fun, sparsity, start = _problem(0)
    ours = SparseDifference(fun, sparsity)
    for x in (start, start - 0.3, np.linspace(-1.0, 1.0, len(start))):
        expected = approx_derivative(fun, x, method="2-point", sparsity=sparsity)
        got = ours(x)
        assert got.shape == expected.shape
        assert np.array_equal(got.toarray(), expected.toarray())
        # the same compressed layout too: trust-region products sum each row in its order
        assert np.array_equal(got.indptr, expected.indptr)
        assert np.array_equal(got.indices, expected.indices)
        assert np.array_equal(got.data, expected.data)


def test_the_fit_is_scipys_bit_for_bit() -> None:
    for seed in (1, 2):
        fun, sparsity, start = _problem(seed)
        expected = least_squares(fun, start, method="trf", x_scale="jac", jac_sparsity=sparsity)
        jacobian = SparseDifference(fun, sparsity)
        got = least_squares(jacobian.fun, start, method="trf", x_scale="jac", jac=jacobian)
        assert expected.nfev > 5
        assert np.array_equal(got.x, expected.x)
        assert got.nfev == expected.nfev
        assert np.array_equal(got.jac.toarray(), expected.jac.toarray())
