"""Through cracks at an open hole against Bowie's tabulated values, DSTO's CRKGRW fits and the
exact limits, and their critical crack by hand at three stresses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from model.crack_cases.hole import CrackAtHole
from model.crack_cases.residual_strength import Toughness, critical_crack
from tests.model.crack_cases.hand import SIGMA_Y, by_criterion, first_root

# Bowie (1956), one crack at an open hole in uniaxial tension (Tada 1973 p. 19.1): a/r -> beta
BOWIE_ONE = {0.1: 2.73, 0.2: 2.30, 0.3: 2.04, 0.4: 1.86, 0.5: 1.73, 0.6: 1.64, 0.8: 1.47,
             1.0: 1.37}  # fmt: skip
# the edge crack's free-surface factor times the hole's Kt of 3, the short-crack limit
SHORT_CRACK_AT_HOLE = 1.1215 * 3.0


def test_crack_at_hole_matches_bowie_and_its_limits() -> None:
    radius = 0.005
    one, two = CrackAtHole(2 * radius, 1), CrackAtHole(2 * radius, 2)
    for ratio, want in BOWIE_ONE.items():
        assert one.beta(np.array([ratio * radius]))[0] == pytest.approx(want, rel=0.01)
    short = np.array([1e-9])
    assert one.beta(short)[0] == pytest.approx(SHORT_CRACK_AT_HOLE, rel=0.01)
    assert two.beta(short)[0] == pytest.approx(SHORT_CRACK_AT_HOLE, rel=0.01)
    # far from the hole: one crack of length a + 2r, two of 2(a + r) (Tada's limits)
    long = np.array([1e3 * radius])
    assert one.beta(long)[0] == pytest.approx(math.sqrt(0.5), rel=0.01)
    assert two.beta(long)[0] == pytest.approx(1.0, rel=0.01)
    # a wide panel is the infinite plate; a narrower one raises beta by the secant
    a = np.array([0.004])
    assert CrackAtHole(2 * radius, 2, 10.0).beta(a)[0] == pytest.approx(two.beta(a)[0], rel=1e-4)
    narrow = CrackAtHole(2 * radius, 2, 0.05).beta(a)[0] / two.beta(a)[0]
    assert narrow == pytest.approx(1.0 / math.sqrt(math.cos(math.pi * 0.009 / 0.05)), rel=1e-12)


def test_two_cracks_at_a_hole_against_an_independent_fit() -> None:
    """No tabulation of Bowie's two-crack values could be found and read (issue 41); the
    independent check is DSTO's CRKGRW fits to Bowie (J. Paul and D. Lombardo, CRKGRW users
    manual, 1988, as easigrow carries them): one crack 0.6762 + 0.8734 / (0.3246 + a/r), two
    0.9439 + 0.6865 / (0.2772 + a/r).  Those fits are themselves ~3 % off Bowie (the one-crack
    fit against the one-crack polynomial, which matches Bowie's table within 1 % above, differs
    as much), so the two-crack polynomial is held to them within 3 % (measured: 2.7 % at most,
    at a/r 2-3), and within 0.5 % for short cracks (a/r <= 0.3, measured 0.4 %)."""
    radius = 0.005
    ratios = np.array([0.05, 0.1, 0.2, 0.3, 0.5, 0.8, 1.0, 1.5, 2.0, 3.0, 5.0, 10.0])
    two = CrackAtHole(2 * radius, 2).beta(ratios * radius)
    one = CrackAtHole(2 * radius, 1).beta(ratios * radius)
    crkgrw_two = 0.9439 + 0.6865 / (0.2772 + ratios)
    crkgrw_one = 0.6762 + 0.8734 / (0.3246 + ratios)
    assert np.all(np.abs(two / crkgrw_two - 1) < 0.03)
    assert np.all(np.abs(one / crkgrw_one - 1) < 0.035)  # the fits' own error, for scale
    near = ratios <= 0.3
    assert np.all(np.abs(two[near] / crkgrw_two[near] - 1) < 0.005)


@pytest.mark.xfail(
    strict=True,
    reason="issue 41: the two-crack polynomial (Schijve's fit to Bowie) tends to 1 with the "
    "wrong slope in r/(r + a); measured 2.4 % below the limit at a/r = 20, 1.1 % at 50",
)
def test_two_long_cracks_at_a_hole_are_one_crack_through_the_hole() -> None:
    """Far from the hole two cracks of length a are one crack of half-length a + r with a small
    hole at its centre, and a hole there changes K only at second order in r/(a + r) (it
    removes material where the crack's own field is near uniform): beta -> sqrt(1 + r/a) to
    within (r/(a + r))**2, 0.23 % at a/r = 20 and 0.04 % at 50; held here to 0.5 %."""
    radius = 0.005
    ratios = np.array([20.0, 30.0, 50.0])
    beta = CrackAtHole(2 * radius, 2).beta(ratios * radius)
    assert np.all(np.abs(beta / np.sqrt(1 + 1 / ratios) - 1) < 0.005)


# Bowie's polynomials in l = 1 / (1 + a/r), as the case's docstring quotes them
_ONE = (0.707, -0.18, 6.55, -10.54, 6.85)
_TWO = (1.0, -0.15, 3.46, -4.47, 3.52)


def _beta_by_hand(a: float, diameter: float, cracks: int, width: float | None) -> float:
    """Bowie's polynomial, times sqrt(sec(pi (n a / 2 + r) / W)) in a finite width."""
    radius = 0.5 * diameter
    ratio = 1 / (1 + a / radius)
    beta = sum(c * ratio**k for k, c in enumerate(_ONE if cracks == 1 else _TWO))
    if width is None:
        return beta
    return beta / math.sqrt(math.cos(math.pi * (0.5 * cracks * a + radius) / width))


@pytest.mark.parametrize(
    ("cracks", "width", "criteria"),
    [
        (1, 0.2, ("extent", "fracture", "net_section_yield")),
        (2, 0.2, ("fracture", "fracture", "net_section_yield")),
        (1, None, ("fracture", "fracture", "fracture")),
        (2, None, ("fracture", "fracture", "fracture")),
    ],
)
def test_critical_crack_at_hole_by_hand_at_three_stresses(
    cracks: int, width: float | None, criteria: tuple[str, str, str]
) -> None:
    """A 10 mm hole, K_c 60: the first crack where K = K_c (a uniform scan, bisected, on the
    closed form written out above); net-section yield where S W = sigma_y (W - d - n a); the
    one crack's ligament, (W - d)/2, severed at 100 MPa before either.  An infinite plate has
    no net section to yield: fracture only."""
    diameter, k_c = 0.01, 60.0
    case = CrackAtHole(diameter, cracks, width)
    toughness = Toughness(k_c, "K_c", SIGMA_Y)
    for stress, criterion in zip((100.0, 200.0, 320.0), criteria, strict=True):

        def k_less_kc(a: float, s: float = stress) -> float:
            return _beta_by_hand(a, diameter, cracks, width) * s * math.sqrt(math.pi * a) - k_c

        if width is None:
            extent, net = 10.0, math.inf  # model.crack_cases.base.UNBOUNDED_M: no section
        else:
            extent = 0.5 * (width - diameter)
            net = (width * (1 - stress / SIGMA_Y) - diameter) / cracks
            net = net if net < extent else math.inf  # the ligament severed first
        fracture = first_root(k_less_kc, 1e-4, extent * (1 - 1e-9))
        want, governs = by_criterion(fracture, net, extent)
        got = critical_crack(case, stress, toughness, 1e-4)
        assert (got.criterion, governs) == (criterion, criterion), stress
        assert got.crack_length_m == pytest.approx(want, rel=1e-8), stress
        assert got.yield_crack_m == (None if net == math.inf else pytest.approx(net, rel=1e-8))
