"""Crack cases against their sources' tabulated values and independent closed forms, their
tables against the closed form, and the critical crack against hand calculations."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from scipy.special import ellipe

from model.crack_cases import CrackCaseError, case_from_dict
from model.crack_cases.base import CrackCase
from model.crack_cases.centre import CentreCrack
from model.crack_cases.corner import CornerCrackAtHole
from model.crack_cases.edge import SingleEdgeCrack
from model.crack_cases.hole import CrackAtHole
from model.crack_cases.residual_strength import (
    Toughness,
    critical_crack,
    residual_strength,
    toughness_for,
)
from model.crack_cases.surface import SurfaceCrack
from model.crack_cases.table import UserTable
from model.crack_cases.tabulate import TOLERANCE, beta_curve

# Isida's series solution for the centre crack, as tabulated in Tada, Paris and Irwin (1973),
# p. 2.2: 2a/W -> beta
ISIDA = {0.1: 1.0060, 0.2: 1.0246, 0.3: 1.0577, 0.4: 1.1094, 0.5: 1.1867, 0.6: 1.3033,
         0.7: 1.4882, 0.8: 1.8160, 0.9: 2.5776}  # fmt: skip
# Gross and Srawley's collocation values for the single edge crack (Tada 1973, p. 2.10): a/W
GROSS_SRAWLEY = {0.1: 1.19, 0.2: 1.37, 0.3: 1.66, 0.4: 2.11, 0.5: 2.82, 0.6: 4.03}
# Bowie (1956), one crack at an open hole in uniaxial tension (Tada 1973 p. 19.1): a/r -> beta
BOWIE_ONE = {0.1: 2.73, 0.2: 2.30, 0.3: 2.04, 0.4: 1.86, 0.5: 1.73, 0.6: 1.64, 0.8: 1.47,
             1.0: 1.37}  # fmt: skip
# the edge crack's free-surface factor times the hole's Kt of 3, the short-crack limit
SHORT_CRACK_AT_HOLE = 1.1215 * 3.0


def test_centre_crack_matches_isida() -> None:
    width = 0.2
    for ratio, want in ISIDA.items():
        a = np.array([0.5 * ratio * width])
        assert CentreCrack(width).beta(a)[0] == pytest.approx(want, rel=1e-3)
        if ratio <= 0.7:
            assert CentreCrack(width, "feddersen").beta(a)[0] == pytest.approx(want, rel=3e-3)


def test_edge_crack_matches_gross_srawley_by_both_fits() -> None:
    width = 0.1
    for ratio, want in GROSS_SRAWLEY.items():
        a = np.array([ratio * width])
        assert SingleEdgeCrack(width).beta(a)[0] == pytest.approx(want, rel=0.01)
        assert SingleEdgeCrack(width, "brown_srawley").beta(a)[0] == pytest.approx(want, rel=0.01)
    assert SingleEdgeCrack(width).beta(np.array([1e-9]))[0] == pytest.approx(1.122, rel=1e-3)


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


def test_surface_crack_against_the_elliptical_crack() -> None:
    shallow = np.array([1e-9])
    # a/t -> 0 at the deepest point: M1 / sqrt(Q), the values Newman and Raju's equation gives
    # for a semicircle (1.04 / sqrt(2.464)) and a/c = 0.5
    assert SurfaceCrack(0.01, 1.0, 1.0).beta(shallow)[0] == pytest.approx(0.66254, rel=1e-4)
    assert SurfaceCrack(0.01, 1.0, 0.5).beta(shallow)[0] == pytest.approx(0.89596, rel=1e-4)
    # Q is the square of Irwin's elliptic integral (Green and Sneddon's exact embedded crack)
    from model.crack_cases.newman_raju import shape_factor

    for aspect in (0.2, 0.4, 0.6, 0.8, 1.0):
        exact = ellipe(1.0 - aspect**2) ** 2
        assert shape_factor(aspect) == pytest.approx(exact, rel=2e-3)
    # the two branches meet at a semicircle, within the published constants' rounding
    # (M2: 0.2017 against 0.2; M3: -0.106 against -0.11)
    a = np.array([0.004])
    below, above = SurfaceCrack(0.01, 0.2, 1 - 1e-9), SurfaceCrack(0.01, 0.2, 1 + 1e-9)
    for point in ("depth", "surface"):
        b = SurfaceCrack(0.01, 0.2, 1 - 1e-9, point).beta(a)[0]
        assert b == pytest.approx(SurfaceCrack(0.01, 0.2, 1 + 1e-9, point).beta(a)[0], rel=1e-3)
    assert below.beta(a)[0] == pytest.approx(above.beta(a)[0], rel=1e-3)


def test_an_evolving_surface_crack_follows_the_two_point_growth() -> None:
    """dc/da = (K_c / K_a)**m along the path, and fronts started from any shape converge on
    the one Newman and Raju's life predictions show under tension, a/c ~ 0.8."""
    m, t = 3.0, 0.01
    shapes = {
        start: SurfaceCrack(t, 0.2, start, growth_exponent=m, shape_at_depth_m=0.0005)
        for start in (0.2, 0.5, 1.0, 1.6)
    }
    deep = np.array([0.6 * t])
    reached = np.array([float(case.aspect_at(deep)[0]) for case in shapes.values()])
    assert np.all((reached > 0.75) & (reached < 0.9)), reached
    assert reached.max() - reached.min() < 0.05
    case = shapes[0.2]
    a = np.array([0.002, 0.0021])
    c = a / case.aspect_at(a)
    middle = np.array([0.00205])
    k = case.aspect_at(middle)
    surface = SurfaceCrack(t, 0.2, float(k[0]), "surface").beta(middle)
    depth = SurfaceCrack(t, 0.2, float(k[0])).beta(middle)
    assert (c[1] - c[0]) / (a[1] - a[0]) == pytest.approx(
        float((surface / depth)[0] ** m), rel=1e-3
    )
    # below the depth where its shape is given, it is held
    assert case.aspect_at(np.array([0.0002]))[0] == pytest.approx(0.2, rel=1e-12)
    with pytest.raises(ValueError, match="shape_at_depth_m"):
        SurfaceCrack(t, 0.2, 0.5, growth_exponent=m)


def test_corner_crack_at_hole_is_newman_raju_written_out() -> None:
    """One point worked by hand from NASA TM 83200's equations: two cracks, a/c = 0.8,
    a = 2 mm, t = 5 mm, r = 4 mm, W = 80 mm, at the bore (phi = pi/2)."""
    k, a, t, r, b = 0.8, 0.002, 0.005, 0.004, 0.04
    c, depth = a / k, a / t
    m1, m2 = 1.13 - 0.09 * k, -0.54 + 0.89 / (0.2 + k)
    m3 = 0.5 - 1 / (0.65 + k) + 14 * (1 - k) ** 24
    lam = 1 / (1 + (c / r) * math.cos(0.85 * math.pi / 2))
    g2 = (1 + 0.358 * lam + 1.425 * lam**2 - 1.578 * lam**3 + 2.156 * lam**4) / (1 + 0.13 * lam**2)
    g3 = (1 + 0.04 * k) * 1.1 * (0.85 + 0.15 * depth**0.25)
    polynomial = (m1 + m2 * depth**2 + m3 * depth**4) * g2 * g3 / math.sqrt(1 + 1.464 * k**1.65)

    def width_factor(n: int) -> float:
        secants = math.cos(math.pi * r / (2 * b)) * math.cos(
            math.pi * (2 * r + n * c) / (4 * (b - c) + 2 * n * c) * math.sqrt(depth)
        )
        return 1 / math.sqrt(secants)

    two = CornerCrackAtHole(2 * r, t, 2 * b, k, 2).beta(np.array([a]))[0]
    assert two == pytest.approx(polynomial * width_factor(2), rel=1e-12)
    one = CornerCrackAtHole(2 * r, t, 2 * b, k, 1).beta(np.array([a]))[0]
    ratio = math.sqrt((4 / math.pi + a * c / (2 * t * r)) / (4 / math.pi + a * c / (t * r)))
    assert one == pytest.approx(polynomial * width_factor(1) * ratio, rel=1e-12)


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
    assert curve.warning is not None and "a/t = 0.8" in curve.warning
    assert curve.table.crack_length_m[-1] == pytest.approx(0.008)
    corner = beta_curve(CornerCrackAtHole(0.01, 0.005, 0.1, 1.0), 0.0005, 0.008)
    assert corner.warning is not None and "through crack" in corner.warning
    with pytest.raises(ValueError, match="initial_crack_m"):
        beta_curve(SingleEdgeCrack(0.01), 0.009, 0.0095)


def test_case_from_dict_names_the_dimension() -> None:
    case = case_from_dict({"type": "centre_crack", "width_m": 0.3})
    assert case == CentreCrack(0.3)
    assert case_from_dict(case.to_dict()) == case
    table = case_from_dict(
        {"type": "table", "crack_length_m": [0.001, 0.01], "beta_values": [1, 2]}
    )
    assert isinstance(table, UserTable)
    for data, field in (
        ({"type": "centre"}, "type"),
        ({"type": "centre_crack"}, "width_m"),
        ({"type": "centre_crack", "width_m": -1.0}, "width_m"),
        ({"type": "centre_crack", "width_m": 0.2, "depth_m": 1.0}, "depth_m"),
        ({"type": "surface_crack", "thickness_m": 0.01, "width_m": 0.1, "aspect_ratio": 3}, "aspect_ratio"),
        ({"type": "corner_crack_at_hole", "hole_diameter_m": 0.001, "thickness_m": 0.01,
          "width_m": 0.1, "aspect_ratio": 1.0}, "hole_diameter_m"),
        ({"type": "through_crack_at_hole", "hole_diameter_m": 0.01, "width_m": 0.015}, "width_m"),
        ({"type": "surface_crack", "thickness_m": 0.01, "width_m": 0.1, "aspect_ratio": "0.5"},
         "aspect_ratio"),
        ({"type": "through_crack_at_hole", "hole_diameter_m": 0.01, "cracks": True}, "cracks"),
        ({"type": "surface_crack", "thickness_m": 0.01, "width_m": 0.1, "aspect_ratio": 0.5,
          "growth_exponent": 3.0}, "shape_at_depth_m"),
    ):  # fmt: skip
        with pytest.raises(CrackCaseError) as caught:
            case_from_dict(data)
        assert caught.value.field == field, (data, str(caught.value))


def _bisect(function: Callable[[float], float], low: float, high: float) -> float:
    """The hand calculation's root: plain bisection to 1e-13 m."""
    assert function(low) < 0 < function(high)
    while high - low > 1e-13:
        middle = 0.5 * (low + high)
        low, high = (middle, high) if function(middle) < 0 else (low, middle)
    return 0.5 * (low + high)


K_C = 100.0
SIGMA_Y = 350.0


def test_critical_centre_crack_by_hand_at_three_stresses() -> None:
    """Feddersen: K = S sqrt(pi a sec(pi a / W)) = K_c; net-section yield at
    a = W/2 (1 - S / sigma_y).  At 100 and 150 MPa fracture comes first, at 330 MPa yield."""
    width = 0.5
    case = CentreCrack(width, "feddersen")
    toughness = Toughness(K_C, "K_c", SIGMA_Y)
    for stress, criterion in (
        (100.0, "fracture"),
        (150.0, "fracture"),
        (330.0, "net_section_yield"),
    ):

        def k_less_kc(a: float, s: float = stress) -> float:
            return s * math.sqrt(math.pi * a / math.cos(math.pi * a / width)) - K_C

        fracture = _bisect(k_less_kc, 1e-4, 0.5 * width - 1e-9)
        net = 0.5 * width * (1 - stress / SIGMA_Y)
        got = critical_crack(case, stress, toughness, 0.001)
        assert got.criterion == criterion
        assert got.crack_length_m == pytest.approx(min(fracture, net), rel=1e-9)
        assert got.fracture_crack_m == pytest.approx(fracture, rel=1e-9)
        assert got.yield_crack_m == pytest.approx(net, rel=1e-9)


def test_critical_crack_of_every_case_by_hand_at_three_stresses() -> None:
    """For the other cases: the first crack where beta(a) S sqrt(pi a) = K_c by bisection
    on the closed form, or the net section's area formula solved by hand."""
    toughness = Toughness(K_C, "K_c", SIGMA_Y)
    width, t = 0.2, 0.006
    net_yield = {  # crack where S A_gross / A_net(a) = sigma_y, by hand
        "edge": lambda s: width * (1 - s / SIGMA_Y),
        "hole": lambda s: (width * (1 - s / SIGMA_Y) - 0.01) / 2,
        "surface": lambda s: math.sqrt(width * t * (1 - s / SIGMA_Y) * 0.8 / (0.5 * math.pi)),
    }
    cases = {
        "edge": SingleEdgeCrack(width),
        "hole": CrackAtHole(0.01, 2, width),
        "surface": SurfaceCrack(t, width, 0.8),
    }
    for name, case in cases.items():
        extent = case.extent_m()
        for stress in (120.0, 200.0, 300.0):

            def k_less_kc(a: float, s: float = stress, c: CrackCase = case) -> float:
                return float(c.beta(np.array([a]))[0]) * s * math.sqrt(math.pi * a) - K_C

            high = extent * (1 - 1e-9)
            fracture = _bisect(k_less_kc, 1e-4, high) if k_less_kc(high) > 0 else math.inf
            net = net_yield[name](stress)
            got = critical_crack(case, stress, toughness, 1e-4)
            want = min(fracture, net, extent)
            assert got.crack_length_m == pytest.approx(want, rel=1e-8), (name, stress)
            by_criterion = {fracture: "fracture", net: "net_section_yield", extent: "extent"}
            assert got.criterion == by_criterion[want]
    # corner crack and Bowie's infinite plate: fracture only (no net section / unchecked)
    infinite = CrackAtHole(0.01, 1)
    for stress in (100.0, 200.0, 300.0):

        def k_hole(a: float, s: float = stress) -> float:
            return float(infinite.beta(np.array([a]))[0]) * s * math.sqrt(math.pi * a) - K_C

        got = critical_crack(infinite, stress, toughness, 1e-4)
        assert got.criterion == "fracture"
        assert got.yield_crack_m is None
        assert got.crack_length_m == pytest.approx(_bisect(k_hole, 1e-4, 5.0), rel=1e-8)


@pytest.mark.parametrize(("cracks", "k_c"), [(1, 45.0), (2, 50.0)])
def test_critical_corner_crack_by_hand_at_three_stresses(cracks: int, k_c: float) -> None:
    """A corner crack at an 8 mm hole in a 60 x 6 mm section, a/c = 1: at 200 MPa it reaches
    the far face (a = t) first, at 260 MPa it fractures (K = K_c by bisection on the closed
    form), at 300 MPa the net section yields: S W t = sigma_y (W t - d t - n pi a**2 / 4 (c/a)),
    a = sqrt(4 (a/c) (W t (1 - S / sigma_y) - d t) / (n pi)).  Without a yield strength the
    net section is not checked."""
    width, t, d = 0.06, 0.006, 0.008
    corner = CornerCrackAtHole(d, t, width, 1.0, cracks)
    toughness = Toughness(k_c, "K_c", SIGMA_Y)
    high = corner.extent_m() * (1 - 1e-9)
    for stress, criterion in ((200.0, "extent"), (260.0, "fracture"), (300.0, "net_section_yield")):

        def k_corner(a: float, s: float = stress) -> float:
            return float(corner.beta(np.array([a]))[0]) * s * math.sqrt(math.pi * a) - k_c

        fracture = _bisect(k_corner, 1e-4, high) if k_corner(high) > 0 else math.inf
        room = width * t * (1 - stress / SIGMA_Y) - d * t
        net = (
            math.sqrt(4 * room / (cracks * math.pi))
            if 0 < room < math.pi * t * t / 4 * cracks
            else math.inf
        )
        got = critical_crack(corner, stress, toughness, 1e-4)
        want = min(fracture, net, corner.extent_m())
        assert got.criterion == criterion, stress
        assert got.crack_length_m == pytest.approx(want, rel=1e-8)
        assert got.fracture_crack_m == (
            None if fracture == math.inf else pytest.approx(fracture, rel=1e-8)
        )
        assert got.yield_crack_m == (None if net == math.inf else pytest.approx(net, rel=1e-8))
        by_k_alone = critical_crack(corner, stress, Toughness(k_c, "K_c", None), 1e-4)
        assert by_k_alone.yield_crack_m is None
        assert by_k_alone.criterion == ("extent" if fracture == math.inf else "fracture")


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

        fracture = _bisect(k_less_kc, 1e-3, 0.1 - 1e-9)
        net = 0.1 * (1 - stress / SIGMA_Y)
        got = critical_crack(case, stress, toughness, 1e-3)
        assert got.criterion == criterion
        assert got.crack_length_m == pytest.approx(min(fracture, net), rel=1e-9)


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
