"""The single edge crack against Gross and Srawley's collocation values by both fits, and its
critical crack by hand at three stresses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from model.crack_cases.edge import SingleEdgeCrack
from model.crack_cases.residual_strength import Toughness, critical_crack
from tests.model.crack_cases.hand import K_C, SIGMA_Y, by_criterion, first_root

# Gross and Srawley's collocation values for the single edge crack (Tada 1973, p. 2.10): a/W
GROSS_SRAWLEY = {0.1: 1.19, 0.2: 1.37, 0.3: 1.66, 0.4: 2.11, 0.5: 2.82, 0.6: 4.03}


def test_edge_crack_matches_gross_srawley_by_both_fits() -> None:
    width = 0.1
    for ratio, want in GROSS_SRAWLEY.items():
        a = np.array([ratio * width])
        assert SingleEdgeCrack(width).beta(a)[0] == pytest.approx(want, rel=0.01)
        assert SingleEdgeCrack(width, "brown_srawley").beta(a)[0] == pytest.approx(want, rel=0.01)
    assert SingleEdgeCrack(width).beta(np.array([1e-9]))[0] == pytest.approx(1.122, rel=1e-3)


def _beta_by_hand(method: str, a: float, width: float) -> float:
    """Tada: sqrt(tan x / x) (0.752 + 2.02 l + 0.37 (1 - sin x)**3) / cos x, x = pi l / 2;
    Brown and Srawley: 1.12 - 0.231 l + 10.55 l**2 - 21.72 l**3 + 30.39 l**4; l = a/W."""
    ratio = a / width
    if method == "brown_srawley":
        return 1.12 - 0.231 * ratio + 10.55 * ratio**2 - 21.72 * ratio**3 + 30.39 * ratio**4
    x = 0.5 * math.pi * ratio
    polynomial = 0.752 + 2.02 * ratio + 0.37 * (1 - math.sin(x)) ** 3
    return math.sqrt(math.tan(x) / x) * polynomial / math.cos(x)


@pytest.mark.parametrize("method", ["tada", "brown_srawley"])
def test_critical_edge_crack_by_hand_at_three_stresses(method: str) -> None:
    """The first crack where beta S sqrt(pi a) = K_c (a uniform scan, bisected, on the closed
    form written out above); net-section yield at a = W (1 - S / sigma_y)."""
    width = 0.2
    case = SingleEdgeCrack(width, method)  # type: ignore[arg-type]
    toughness = Toughness(K_C, "K_c", SIGMA_Y)
    for stress, criterion in (
        (120.0, "fracture"),
        (200.0, "fracture"),
        (340.0, "net_section_yield"),
    ):

        def k_less_kc(a: float, s: float = stress) -> float:
            return _beta_by_hand(method, a, width) * s * math.sqrt(math.pi * a) - K_C

        fracture = first_root(k_less_kc, 1e-4, width * (1 - 1e-9))
        net = width * (1 - stress / SIGMA_Y)
        want, governs = by_criterion(fracture, net, width)
        got = critical_crack(case, stress, toughness, 1e-4)
        assert (got.criterion, governs) == (criterion, criterion), stress
        assert got.crack_length_m == pytest.approx(want, rel=1e-8), stress
