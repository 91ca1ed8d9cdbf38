"""Every case's beta(a) as the table the march reads: within 0.1 % of the closed form between
a0 and the final crack, and ended at the validity limit, with a warning, past it."""

from __future__ import annotations

import numpy as np
import pytest

from model.crack_cases.base import CrackCase
from model.crack_cases.centre import CentreCrack
from model.crack_cases.corner import CornerCrackAtHole
from model.crack_cases.edge import SingleEdgeCrack
from model.crack_cases.hole import CrackAtHole
from model.crack_cases.surface import SurfaceCrack
from model.crack_cases.table import UserTable
from model.crack_cases.tabulate import TOLERANCE, beta_curve

ALL_CASES: list[tuple[CrackCase, float, float]] = [
    (CentreCrack(0.3), 0.002, 0.12),
    (CentreCrack(0.3, "feddersen"), 0.002, 0.1),
    (SingleEdgeCrack(0.1), 0.001, 0.07),
    (SingleEdgeCrack(0.1, "brown_srawley"), 0.001, 0.06),
    (CrackAtHole(0.006, 1), 0.0005, 0.05),
    (CrackAtHole(0.006, 2, 0.1), 0.0005, 0.02),
    (SurfaceCrack(0.008, 0.1, 0.7), 0.0005, 0.0064),
    (SurfaceCrack(0.008, 0.1, 1.5, "surface"), 0.0005, 0.0064),
    (CornerCrackAtHole(0.008, 0.006, 0.06, 1.0, 1), 0.0003, 0.006),
    (CornerCrackAtHole(0.008, 0.006, 0.06, 0.5, 2, "surface"), 0.0003, 0.005),
    (UserTable((0.001, 0.01, 0.05), (1.1, 1.2, 1.6)), 0.001, 0.05),
    (SurfaceCrack(0.008, 0.1, 0.3, growth_exponent=3.5, shape_at_depth_m=0.0005), 0.0005, 0.0064),
]


@pytest.mark.parametrize(("case", "a0", "a_end"), ALL_CASES)
def test_table_reads_within_tolerance_of_the_closed_form(
    case: CrackCase, a0: float, a_end: float
) -> None:
    curve = beta_curve(case, a0, a_end)
    assert curve.warning is None
    assert curve.table.crack_length_m[0] == pytest.approx(a0)
    assert curve.table.crack_length_m[-1] == pytest.approx(a_end)
    # checked off the tabulation's own grid, at random cracks, as the march reads the table
    cracks = np.sort(np.random.default_rng(0).uniform(a0, a_end, 20_000))
    reading = np.array([curve.table.value_at(float(a)) for a in cracks[::50]])
    exact = case.beta(cracks[::50])
    assert np.max(np.abs(reading / exact - 1)) < TOLERANCE
    assert curve.max_relative_error < TOLERANCE


def test_leaving_the_validity_range_is_said_and_the_table_ends_there() -> None:
    curve = beta_curve(SurfaceCrack(0.01, 0.2, 1.0), 0.001, 0.009)
    assert curve.validity.crack_length_m == pytest.approx(0.008)
    assert curve.warning == (
        "the crack leaves the case's validity range at a = 8.00 mm (a/t = 0.8 (Newman-Raju); "
        "t = 10.00 mm, W = 200.00 mm); beta is held at its value there up to a = 9.00 mm"
    )
    assert curve.table.crack_length_m[-1] == pytest.approx(0.008)
    corner = beta_curve(CornerCrackAtHole(0.01, 0.005, 0.1, 1.0), 0.0005, 0.008)
    assert corner.warning is not None and "through crack" in corner.warning
    with pytest.raises(ValueError, match="initial_crack_m"):
        beta_curve(SingleEdgeCrack(0.01), 0.009, 0.0095)
