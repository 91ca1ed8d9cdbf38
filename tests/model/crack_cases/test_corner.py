"""The corner crack at a hole: Newman and Raju's equations written out, against the surface
crack's shared terms and a second transcription, and its critical crack by hand at three
stresses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from model.crack_cases.corner import CornerCrackAtHole
from model.crack_cases.newman_raju import angle_factor, depth_terms, shape_factor, surface_term
from model.crack_cases.residual_strength import Toughness, critical_crack
from model.crack_cases.surface import SurfaceCrack
from tests.model.crack_cases.hand import SIGMA_Y, by_criterion, first_root


def _beta_by_hand(
    a: float, aspect: float, thickness: float, radius: float, width: float, cracks: int, phi: float
) -> float:
    """NASA TM 83200's corner crack at a hole (a/c <= 1) term by term, as the case's docstring
    quotes it: [M1 + M2 (a/t)**2 + M3 (a/t)**4] g1 g2 g3 f_phi f_w / sqrt(Q), times the
    one-crack ratio for one crack."""
    k, depth = aspect, a / thickness
    assert 0 < k <= 1
    c, b = a / k, 0.5 * width
    m1, m2 = 1.13 - 0.09 * k, -0.54 + 0.89 / (0.2 + k)
    m3 = 0.5 - 1 / (0.65 + k) + 14 * (1 - k) ** 24
    g1 = 1 + (0.1 + 0.35 * depth**2) * (1 - math.sin(phi)) ** 2
    lam = 1 / (1 + (c / radius) * math.cos(0.85 * phi))
    g2 = (1 + 0.358 * lam + 1.425 * lam**2 - 1.578 * lam**3 + 2.156 * lam**4) / (1 + 0.13 * lam**2)
    g3 = (1 + 0.04 * k) * (1 + 0.1 * (1 - math.cos(phi)) ** 2) * (0.85 + 0.15 * depth**0.25)
    f_phi = (k**2 * math.cos(phi) ** 2 + math.sin(phi) ** 2) ** 0.25
    secants = math.cos(math.pi * radius / (2 * b)) * math.cos(
        math.pi * (2 * radius + cracks * c) / (4 * (b - c) + 2 * cracks * c) * math.sqrt(depth)
    )
    beta = (m1 + m2 * depth**2 + m3 * depth**4) * g1 * g2 * g3 * f_phi / math.sqrt(secants)
    beta /= math.sqrt(1 + 1.464 * k**1.65)
    if cracks == 1:
        beta *= math.sqrt(
            (4 / math.pi + a * c / (2 * thickness * radius))
            / (4 / math.pi + a * c / (thickness * radius))
        )
    return beta


@pytest.mark.parametrize("cracks", [1, 2])
@pytest.mark.parametrize("point", ["bore", "surface"])
def test_corner_crack_at_hole_is_newman_raju_written_out(cracks: int, point: str) -> None:
    """a/c = 0.8, a = 2 mm, t = 5 mm, r = 4 mm, W = 80 mm, at the bore (phi = pi/2) and on
    the plate's face (phi = 0)."""
    k, a, t, r, width = 0.8, 0.002, 0.005, 0.004, 0.08
    phi = 0.5 * math.pi if point == "bore" else 0.0
    case = CornerCrackAtHole(2 * r, t, width, k, cracks, point)  # type: ignore[arg-type]
    want = _beta_by_hand(a, k, t, r, width, cracks, phi)
    assert case.beta(np.array([a]))[0] == pytest.approx(want, rel=1e-12)


@pytest.mark.parametrize("cracks", [1, 2])
@pytest.mark.parametrize(
    ("aspect", "depth_ratio", "point"),
    [(0.2, 0.2, "bore"), (0.5, 0.6, "surface"), (1.0, 0.4, "bore"), (1.6, 0.8, "surface")],
)
def test_corner_crack_at_hole_shares_the_surface_cracks_terms(
    aspect: float, depth_ratio: float, point: str, cracks: int
) -> None:
    """The corner crack at a hole is the surface crack's M1, M2, M3, g1 and f_phi over
    sqrt(Q) (checked against easigrow, test_surface.py) times the hole's g2 and g3, the
    width's f_w and, for one crack, Shah's ratio: divided by those, it is that polynomial.

    The one other transcription found, easigrow's disabled `dccht-newman81` (src/beta.rs, from
    Murakami's handbook vol. 2 p. 716), differs from TM 83200's equations as this case and the
    literature quote them in g2 (Bowie's two-crack polynomial over 1 + 0.13 l**2: 3.7 % lower
    at l = 0.2, equal at l = 1), g3 (0.8 + 0.2 (a/t)**(1/4): 2.9 % lower at a/t = 0.05, equal at
    a/t = 1) and f_w (the surface crack's), and drops M3's 14 (1 - a/c)**24 and swaps g1's
    branches, both of which TM 83200 shares with the surface crack and easigrow's own
    seft-newman84 keeps; it is not taken as a check (docs/api.md says so)."""
    thickness, radius, width = 0.005, 0.004, 0.5
    a = depth_ratio * thickness
    phi = 0.5 * math.pi if point == "bore" else 0.0
    case = CornerCrackAtHole(2 * radius, thickness, width, aspect, cracks, point)  # type: ignore[arg-type]
    beta = float(case.beta(np.array([a]))[0])
    c, b = a / aspect, 0.5 * width
    lam = 1 / (1 + (c / radius) * math.cos(0.85 * phi))
    g2 = (1 + 0.358 * lam + 1.425 * lam**2 - 1.578 * lam**3 + 2.156 * lam**4) / (1 + 0.13 * lam**2)
    lead = 1 + 0.04 * aspect if aspect <= 1 else 1.13 - 0.09 / aspect
    g3 = lead * (1 + 0.1 * (1 - math.cos(phi)) ** 2) * (0.85 + 0.15 * depth_ratio**0.25)
    secants = math.cos(math.pi * radius / (2 * b)) * math.cos(
        math.pi
        * (2 * radius + cracks * c)
        / (4 * (b - c) + 2 * cracks * c)
        * math.sqrt(depth_ratio)
    )
    hole = g2 * g3 / math.sqrt(secants)
    if cracks == 1:
        hole *= math.sqrt(
            (4 / math.pi + a * c / (2 * thickness * radius))
            / (4 / math.pi + a * c / (thickness * radius))
        )
    m1, m2, m3 = (float(m) for m in depth_terms(aspect))
    polynomial = (m1 + m2 * depth_ratio**2 + m3 * depth_ratio**4) * float(
        surface_term(aspect, np.array([depth_ratio]), phi)[0]
    )
    shared = polynomial * float(angle_factor(aspect, phi)) / math.sqrt(float(shape_factor(aspect)))
    assert beta / hole == pytest.approx(shared, rel=1e-12)
    # and the shared part is the surface crack's at the same point (its f_w -> 1 in a wide plate)
    surface_point = "depth" if point == "bore" else "surface"
    wide = SurfaceCrack(thickness, 1e3, aspect, surface_point)  # type: ignore[arg-type]
    assert shared == pytest.approx(float(wide.beta(np.array([a]))[0]), rel=1e-6)


@pytest.mark.parametrize("cracks", [1, 2])
@pytest.mark.parametrize("point", ["bore", "surface"])
@pytest.mark.parametrize(
    ("aspect", "depth_ratio"), [(0.2, 0.4), (0.5, 0.2), (0.6, 0.5), (1.0, 0.3), (1.0, 0.7)]
)
def test_corner_crack_at_hole_against_a_course_transcription(
    aspect: float, depth_ratio: float, point: str, cracks: int
) -> None:
    """A second, independent transcription of the corner crack at a hole (a/c <= 1): Wichita
    State's AE 737 course (ndaman/damagetolerance, examples/'Cracks Around a Hole.ipynb',
    cases 3 and 4, from the course text's equations 3.1g-3.1n and 3.2) has the same M1-M3,
    g1, g2, g3, f_phi, f_w, Q and one-crack ratio as this case, and one term more,
    g4 = 1 - 0.7 (1 - a/t)(a/c - 0.2)(1 - a/c).  It agrees with this case to rounding where g4
    is 1 (a/c = 0.2 or 1), which checks g2, g3, f_w and the one-crack ratio; between, the two
    differ by exactly g4, which the course's equations carry and TM 83200 as this case quotes
    it does not (this case 9.8 % above them at a/c = 0.6, a/t = 0.2; 12.6 % at most, a/c = 0.6,
    a/t -> 0).  Which is right is not settled here: the course names no source for g4, and
    neither TM 83200 nor Newman and Raju's later TM 85793 (1984) could be read (docs/api.md).
    The course's equations are this module's _beta_by_hand times g4."""
    thickness, radius, width = 0.005, 0.004, 0.5
    phi = 0.5 * math.pi if point == "bore" else 0.0
    a = depth_ratio * thickness
    case = CornerCrackAtHole(2 * radius, thickness, width, aspect, cracks, point)  # type: ignore[arg-type]
    ours = float(case.beta(np.array([a]))[0])
    g4 = 1 - 0.7 * (1 - depth_ratio) * (aspect - 0.2) * (1 - aspect)
    course = _beta_by_hand(a, aspect, thickness, radius, width, cracks, phi) * g4
    assert ours * g4 == pytest.approx(course, rel=1e-12)
    if aspect in (0.2, 1.0):
        assert ours == pytest.approx(course, rel=1e-12)
    else:
        assert abs(ours / course - 1) > 0.05


@pytest.mark.parametrize(
    ("cracks", "point", "k_c"),
    [(1, "bore", 45.0), (2, "bore", 50.0), (1, "surface", 45.0), (2, "surface", 45.0)],
)
def test_critical_corner_crack_by_hand_at_three_stresses(
    cracks: int, point: str, k_c: float
) -> None:
    """A corner crack at an 8 mm hole in a 60 x 6 mm section, a/c = 1: at 200 MPa it reaches
    the far face (a = t) first, at 260 MPa it fractures (K = K_c: a uniform scan, bisected, on
    the equations written out above), at 300 MPa the net section yields:
    S W t = sigma_y (W t - d t - n pi a**2 / 4 (c/a)),
    a = sqrt(4 (a/c) (W t (1 - S / sigma_y) - d t) / (n pi)).  Without a yield strength the
    net section is not checked."""
    width, t, d = 0.06, 0.006, 0.008
    phi = 0.5 * math.pi if point == "bore" else 0.0
    corner = CornerCrackAtHole(d, t, width, 1.0, cracks, point)  # type: ignore[arg-type]
    toughness = Toughness(k_c, "K_c", SIGMA_Y)
    extent = t  # the half length (c = a) reaches the width's half far later
    for stress, criterion in ((200.0, "extent"), (260.0, "fracture"), (300.0, "net_section_yield")):

        def k_corner(a: float, s: float = stress) -> float:
            beta = _beta_by_hand(a, 1.0, t, 0.5 * d, width, cracks, phi)
            return beta * s * math.sqrt(math.pi * a) - k_c

        fracture = first_root(k_corner, 1e-4, extent * (1 - 1e-9))
        room = width * t * (1 - stress / SIGMA_Y) - d * t
        net = math.sqrt(4 * room / (cracks * math.pi)) if room > 0 else math.inf
        net = net if net < extent else math.inf
        want, governs = by_criterion(fracture, net, extent)
        got = critical_crack(corner, stress, toughness, 1e-4)
        assert (got.criterion, governs) == (criterion, criterion), stress
        assert got.crack_length_m == pytest.approx(want, rel=1e-8)
        assert got.fracture_crack_m == (
            None if fracture == math.inf else pytest.approx(fracture, rel=1e-8)
        )
        assert got.yield_crack_m == (None if net == math.inf else pytest.approx(net, rel=1e-8))
        by_k_alone = critical_crack(corner, stress, Toughness(k_c, "K_c", None), 1e-4)
        assert by_k_alone.yield_crack_m is None
        assert by_k_alone.criterion == ("extent" if fracture == math.inf else "fracture")
