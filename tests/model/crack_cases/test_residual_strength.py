"""The residual strength at a crack, its margin over the limit stress, the refusal of a limit
stress the section cannot carry at a0, and which toughness a section's thickness takes (each
case's critical crack by hand is in its family's file)."""

from __future__ import annotations

import math

import pytest

from model.crack_cases.centre import CentreCrack
from model.crack_cases.residual_strength import (
    Toughness,
    critical_crack,
    residual_strength,
    toughness_for,
)
from tests.model.crack_cases.hand import K_C, SIGMA_Y


def test_residual_strength_and_margin() -> None:
    case = CentreCrack(0.5, "feddersen")
    toughness = Toughness(K_C, "K_c", SIGMA_Y)
    a = 0.05
    by_hand = K_C / math.sqrt(math.pi * a / math.cos(math.pi * a / 0.5))
    strength = residual_strength(case, a, toughness)
    assert strength.criterion == "fracture"
    assert strength.stress_mpa == pytest.approx(by_hand, rel=1e-12)
    assert strength.margin_over(150.0) == pytest.approx(by_hand / 150.0 - 1, rel=1e-12)
    # a long crack in a tough sheet: the net section yields first
    tough = Toughness(1000.0, "K_c", SIGMA_Y)
    assert residual_strength(case, 0.2, tough).stress_mpa == pytest.approx(SIGMA_Y * 0.1 / 0.5)
    with pytest.raises(ValueError, match="max_stress_mpa"):
        critical_crack(case, 345.0, toughness, 0.1)


def test_toughness_for_thickness() -> None:
    # plane-strain size 2.5 (34 / 345)**2 = 24.3 mm
    assert toughness_for(34.0, 100.0, 345.0, 0.002).kind == "K_c"
    assert toughness_for(34.0, 100.0, 345.0, 0.03).kind == "K_IC"
    assert toughness_for(34.0, None, 345.0, 0.002).fracture_toughness_mpa_sqrt_m == 34.0
