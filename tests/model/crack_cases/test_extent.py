"""Where each case's crack ends (extent_m) and the words that name it (extent_reason): the
dimension named is the one extent_m equals, so a critical crack set by the end of its case
says which dimension ended it (the catalogue page's "Why")."""

from __future__ import annotations

import pytest

from model.crack_cases.base import UNBOUNDED_M, CrackCase
from model.crack_cases.centre import CentreCrack
from model.crack_cases.corner import CornerCrackAtHole
from model.crack_cases.edge import SingleEdgeCrack
from model.crack_cases.hole import CrackAtHole
from model.crack_cases.surface import SurfaceCrack
from model.crack_cases.table import UserTable

# (case, the end by hand (m), the words' start)
ENDS: list[tuple[CrackCase, float, str]] = [
    (CentreCrack(0.3), 0.15, "2a = W"),
    (SingleEdgeCrack(0.05), 0.05, "a = W"),
    (CrackAtHole(0.01, 2, 0.1), 0.045, "a = (W - 2r)/2"),
    (CrackAtHole(0.01, 1), UNBOUNDED_M, "an infinite plate"),
    # t = 5 mm against (b - r) a/c = (40 - 4) 0.8 = 28.8 mm: the bore first
    (CornerCrackAtHole(0.008, 0.005, 0.08, 0.8), 0.005, "a = t"),
    # t = 4 mm against (10 - 4) 0.2 = 1.2 mm: the plate's edge first
    (CornerCrackAtHole(0.008, 0.004, 0.02, 0.2), 0.0012, "r + c = W/2"),
    # t = 9.8 mm against W/2 a/c = 100 x 0.8 = 80 mm: the back face first
    (SurfaceCrack(0.0098, 0.2, 0.8), 0.0098, "a = t"),
    # t = 20 mm against W/2 a/c = 10 x 0.2 = 2 mm: the plate's edges first
    (SurfaceCrack(0.02, 0.02, 0.2), 0.002, "c = W/2"),
    (UserTable((0.001, 0.01), (1.0, 1.2), 0.05), 0.05, "a = W"),
    (UserTable((0.001, 0.01), (1.0, 1.2)), UNBOUNDED_M, "no width given"),
]


@pytest.mark.parametrize(("case", "end_m", "words"), ENDS)
def test_each_case_names_the_dimension_that_ends_its_crack(
    case: CrackCase, end_m: float, words: str
) -> None:
    assert case.extent_m() == pytest.approx(end_m, rel=1e-12)
    assert case.extent_reason().startswith(words), case.extent_reason()
