"""beta(a) of a crack case as the table every march reads (model.geometry.GeometryTable,
linear between points), with knots placed where the closed form bends so that the linear
reading stays within TOLERANCE of it over [a0, a_end]."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from model.crack_cases.base import CrackCase, ValidityLimit, mm
from model.geometry import MAX_POINTS, GeometryTable

# the march's reading of beta within 0.1 % of the closed form (issue 41)
TOLERANCE = 1e-3
# points per knot interval at which the reading is checked against the closed form
_CHECKS = 4096


@dataclass(frozen=True)
class BetaCurve:
    """The table over [a0, a_end], its largest relative error against the closed form on a
    fine check grid, the case's validity limit, and a warning where a_end passes it (the
    table then ends at the limit and is held beyond, as every table is; its lengths in mm, as
    the reader's)."""

    table: GeometryTable
    max_relative_error: float
    validity: ValidityLimit
    warning: str | None


def beta_curve(
    case: CrackCase, initial_crack_m: float, final_crack_m: float, tolerance: float = TOLERANCE
) -> BetaCurve:
    """Tabulate `case` from initial_crack_m to final_crack_m (m; clipped to the validity
    limit).  Knots are added greedily, each where the linear reading is worst, until the
    relative error is below `tolerance` everywhere on a grid of _CHECKS points (log-spaced
    in a).  Raises ValueError naming initial_crack_m where it lies at or past the validity
    limit or the final crack, and where MAX_POINTS knots cannot reach `tolerance`."""
    validity = case.validity()
    if not 0 < initial_crack_m < validity.crack_length_m:
        raise ValueError(
            f"initial_crack_m ({initial_crack_m:g} m) must lie below the crack case's validity "
            f"limit, a = {validity.crack_length_m:g} m ({validity.reason})"
        )
    if not final_crack_m > initial_crack_m:
        raise ValueError(
            f"the final crack ({final_crack_m:g} m) must exceed initial_crack_m "
            f"({initial_crack_m:g} m)"
        )
    warning = None
    end = final_crack_m
    if final_crack_m > validity.crack_length_m:
        end = validity.crack_length_m
        warning = (
            f"the crack leaves the case's validity range at {case.validity_said()}; beta is "
            f"held at its value there up to a = {mm(final_crack_m)}"
        )
    grid = np.geomspace(initial_crack_m, end, _CHECKS)
    exact = case.beta(grid)
    knots = [0, _CHECKS - 1]
    error = _relative_error(grid, exact, knots)
    while error.max() > tolerance:
        if len(knots) >= MAX_POINTS:
            raise ValueError(
                f"beta of this crack case bends too fast over [{initial_crack_m:g}, {end:g}] m "
                f"for {MAX_POINTS} points within {tolerance:.2%}: give a smaller critical crack"
            )
        knots = sorted({*knots, int(error.argmax())})
        error = _relative_error(grid, exact, knots)
    table = GeometryTable.of(grid[knots].tolist(), exact[knots].tolist())
    return BetaCurve(table, float(error.max()), validity, warning)


def _relative_error(grid: np.ndarray, exact: np.ndarray, knots: list[int]) -> np.ndarray:
    reading = np.interp(grid, grid[knots], exact[knots])
    return np.abs(reading / exact - 1.0)
