"""The centre crack in a finite-width plate against Isida's tabulated values, and its critical
crack by hand at three stresses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from model.crack_cases.centre import CentreCrack
from model.crack_cases.residual_strength import Toughness, critical_crack
from tests.model.crack_cases.hand import K_C, SIGMA_Y, bisect

# Isida's series solution for the centre crack, as tabulated in Tada, Paris and Irwin (1973),
# p. 2.2: 2a/W -> beta
ISIDA = {0.1: 1.0060, 0.2: 1.0246, 0.3: 1.0577, 0.4: 1.1094, 0.5: 1.1867, 0.6: 1.3033,
         0.7: 1.4882, 0.8: 1.8160, 0.9: 2.5776}  # fmt: skip


def test_centre_crack_matches_isida() -> None:
    width = 0.2
    for ratio, want in ISIDA.items():
        a = np.array([0.5 * ratio * width])
        assert CentreCrack(width).beta(a)[0] == pytest.approx(want, rel=1e-3)
        if ratio <= 0.7:
            assert CentreCrack(width, "feddersen").beta(a)[0] == pytest.approx(want, rel=3e-3)


def _beta_by_hand(method: str, a: float, width: float) -> float:
    """Feddersen: sqrt(sec(pi a / W)); Tada: (1 - 0.025 l**2 + 0.06 l**4) times it, l = 2a/W."""
    secant = 1 / math.sqrt(math.cos(math.pi * a / width))
    ratio = 2 * a / width
    return secant if method == "feddersen" else (1 - 0.025 * ratio**2 + 0.06 * ratio**4) * secant


@pytest.mark.parametrize("method", ["feddersen", "tada"])
def test_critical_centre_crack_by_hand_at_three_stresses(method: str) -> None:
    """K = beta S sqrt(pi a) = K_c by bisection on the closed form; net-section yield at
    a = W/2 (1 - S / sigma_y).  At 100 and 150 MPa fracture comes first, at 330 MPa yield."""
    width = 0.5
    case = CentreCrack(width, method)  # type: ignore[arg-type]
    toughness = Toughness(K_C, "K_c", SIGMA_Y)
    for stress, criterion in (
        (100.0, "fracture"),
        (150.0, "fracture"),
        (330.0, "net_section_yield"),
    ):

        def k_less_kc(a: float, s: float = stress) -> float:
            return _beta_by_hand(method, a, width) * s * math.sqrt(math.pi * a) - K_C

        fracture = bisect(k_less_kc, 1e-4, 0.5 * width - 1e-9)
        net = 0.5 * width * (1 - stress / SIGMA_Y)
        got = critical_crack(case, stress, toughness, 0.001)
        assert got.criterion == criterion
        assert got.crack_length_m == pytest.approx(min(fracture, net), rel=1e-9)
        assert got.fracture_crack_m == pytest.approx(fracture, rel=1e-9)
        assert got.yield_crack_m == pytest.approx(net, rel=1e-9)
