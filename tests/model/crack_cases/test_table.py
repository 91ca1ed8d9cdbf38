"""A user's beta table: its critical crack by hand at three stresses."""

from __future__ import annotations

import math

import pytest

from model.crack_cases.residual_strength import Toughness, critical_crack
from model.crack_cases.table import UserTable
from tests.model.crack_cases.hand import SIGMA_Y, bisect


def test_critical_crack_of_a_user_table_by_hand_at_three_stresses() -> None:
    """beta rising linearly from 1.1 at 1 mm to 1.5 at 41 mm in a 100 mm section, K_c 60: K = K_c
    solved by bisection on the linear reading; yield at a = W (1 - S / sigma_y)."""
    case = UserTable((0.001, 0.041), (1.1, 1.5), width_m=0.1)
    toughness = Toughness(60.0, "K_c", SIGMA_Y)
    for stress, criterion in (
        (150.0, "fracture"),
        (250.0, "fracture"),
        (340.0, "net_section_yield"),
    ):

        def k_less_kc(a: float, s: float = stress) -> float:
            beta = 1.1 + 0.4 * (min(a, 0.041) - 0.001) / 0.04
            return beta * s * math.sqrt(math.pi * a) - 60.0

        fracture = bisect(k_less_kc, 1e-3, 0.1 - 1e-9)
        net = 0.1 * (1 - stress / SIGMA_Y)
        got = critical_crack(case, stress, toughness, 1e-3)
        assert got.criterion == criterion
        assert got.crack_length_m == pytest.approx(min(fracture, net), rel=1e-9)
    # without a width the section has no net section to yield: fracture alone
    bare = critical_crack(UserTable((0.001, 0.041), (1.1, 1.5)), 340.0, toughness, 1e-3)
    assert bare.criterion == "fracture" and bare.yield_crack_m is None
