"""A sparse Jacobian by forward differences, as scipy's least_squares takes it from
`jac_sparsity` (scipy.optimize._numdiff: the same columns perturbed together, the same steps,
the same quotients in the same order, so the same bits), with the sparsity's bookkeeping done
once instead of at every iteration.

Why: the measured cracks' trend (model.geometry_trend) crawls thousands of trust-region
iterations on some fleets (4,271 at the wing splice: 12-15 CPU s), and scipy re-derives each
group's nonzeros from the sparsity at each of them, a third of an iteration's time; and each
matrix was then assembled from (row, column, value) triplets, sorted into compressed rows anew
at every iteration (~15 % of the fit): the compressed layout is the same at every x, so it is
derived once and each Jacobian's values are put in its order."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.optimize._numdiff import group_columns
from scipy.sparse import csr_matrix, find, lil_matrix

# scipy's relative step of a forward difference in float64: sqrt(machine epsilon)
_RELATIVE_STEP = float(np.finfo(np.float64).eps ** 0.5)


class SparseDifference:
    """jac(x) for least_squares: d fun / d x at x by forward differences over the nonzeros of
    `sparsity` (residuals, parameters).  fun's value at the x asked for is the one least_squares
    evaluated last (it asks for the Jacobian where it just evaluated), else evaluated here."""

    def __init__(self, fun: Callable[[np.ndarray], np.ndarray], sparsity: lil_matrix) -> None:
        self.shape = sparsity.shape
        self._last: tuple[bytes, np.ndarray] | None = None
        self._fun = fun
        structure = sparsity.tocsc()
        groups = group_columns(structure)
        self._groups = []  # (columns perturbed together, their nonzeros' rows and columns)
        for group in range(int(groups.max()) + 1):
            perturbed = np.equal(group, groups)
            (cols,) = np.nonzero(perturbed)
            rows, within, _ = find(structure[:, cols])
            self._groups.append((perturbed, rows, cols[within]))
        # scipy's csr of the triplets in the groups' order (coo -> csr, duplicates summed: sorted
        # by column in each row), built once with each triplet's position as its value: where
        # each difference goes in every later matrix
        every_row = np.hstack([rows for _, rows, _ in self._groups])
        every_col = np.hstack([cols for _, _, cols in self._groups])
        place = np.arange(1, len(every_row) + 1, dtype=np.float64)
        layout = csr_matrix((place, (every_row, every_col)), self.shape)
        self._order = layout.data.astype(np.int64) - 1
        self._indices, self._indptr = layout.indices, layout.indptr

    def fun(self, x: np.ndarray) -> np.ndarray:
        """fun(x), kept for the Jacobian at x."""
        value = self._fun(x)
        self._last = (x.tobytes(), value)
        return value

    def __call__(self, x0: np.ndarray) -> csr_matrix:
        f0 = self._last[1] if self._last and self._last[0] == x0.tobytes() else self._fun(x0)
        sign = (x0 >= 0).astype(float) * 2 - 1
        h = _RELATIVE_STEP * sign * np.maximum(1.0, np.abs(x0))
        fractions = []
        for perturbed, i, j in self._groups:
            x = x0 + h * perturbed
            dx = x - x0
            df = self._fun(x) - f0
            fractions.append(df[i] / dx[j])
        values = np.hstack(fractions)[self._order]
        layout = (values, self._indices.copy(), self._indptr.copy())
        return csr_matrix(layout, self.shape)
