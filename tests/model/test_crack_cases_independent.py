"""Newman and Raju's surface and corner cracks against an independent implementation and an
exact limit (issue 41: every crack case within 1 % of an independent source).

No tabulation of Newman and Raju's finite-element values, and no readable copy of NASA TM
83200, could be found in the public code, documentation and pages searched (2026-12-02); their
equations are themselves fits within about 5 % of those values, so the check that can be made
is of this transcription against another one, and of the limits where an exact value exists.

The independent implementation is easigrow's `seft-newman84` (the Easigrow/easigrow Rust
crate, src/beta.rs: Newman and Raju, NASA TM 85793, 1984, the same tension equations as TM
83200's), evaluated once from its own reading: its phi is measured from the deepest point
(phi = 0 there, pi/2 at the surface), its half width b is the `sideways` distance, its surface
point's beta is referenced to sqrt(pi c), and it takes the a/c > 1 branch from a/c = 1 on.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from model.crack_cases.corner import CornerCrackAtHole
from model.crack_cases.hole import CrackAtHole
from model.crack_cases.newman_raju import angle_factor, depth_terms, shape_factor, surface_term
from model.crack_cases.surface import SurfaceCrack

# (a/c, a/t, c/b) -> (beta at the deepest point, beta at the surface referenced to sqrt(pi c)),
# as easigrow's seft-newman84 gives them (5 digits)
EASIGROW_SEFT_NEWMAN84 = {
    (0.2, 0.1, 0.05): (1.07503, 0.23726),
    (0.2, 0.6, 0.3): (1.61529, 0.39607),
    (0.5, 0.4, 0.2): (0.99462, 0.57489),
    (0.8, 0.7, 0.4): (0.89724, 0.91267),
    (1.0, 0.5, 0.1): (0.69215, 0.82193),
    (1.0, 0.8, 0.45): (0.79649, 1.05455),
    (1.5, 0.3, 0.2): (0.52337, 0.88005),
    (2.0, 0.6, 0.1): (0.42482, 0.98814),
}
# Koiter's edge crack in a half-plane (Tada, Paris and Irwin 1973, p. 8.1), exact to 4 digits
HALF_PLANE_EDGE = 1.1215


def _surface(aspect: float, depth_ratio: float, c_on_b: float, point: str) -> float:
    thickness = 0.01
    a = depth_ratio * thickness
    width = 2.0 * (a / aspect) / c_on_b
    return float(SurfaceCrack(thickness, width, aspect, point).beta(np.array([a]))[0])  # type: ignore[arg-type]


@pytest.mark.parametrize(("shape", "easigrow"), EASIGROW_SEFT_NEWMAN84.items())
def test_surface_crack_matches_easigrow(
    shape: tuple[float, float, float], easigrow: tuple[float, float]
) -> None:
    """Within 1e-4 (easigrow's 5 digits) at both points, and at a/c = 1, where easigrow takes
    the other branch, within the published constants' rounding (M2 0.2017 against 0.2, M3
    -0.106 against -0.11: measured 0.24 % at a/t = 0.8)."""
    aspect, depth_ratio, c_on_b = shape
    deepest = _surface(aspect, depth_ratio, c_on_b, "depth")
    # ours is referenced to the march's crack, the depth a: K / (S sqrt(pi a))
    at_surface = _surface(aspect, depth_ratio, c_on_b, "surface") * math.sqrt(aspect)
    tolerance = 3e-3 if aspect == 1.0 else 1e-4
    assert deepest == pytest.approx(easigrow[0], rel=tolerance)
    assert at_surface == pytest.approx(easigrow[1], rel=tolerance)


def test_a_long_shallow_surface_crack_is_the_half_plane_edge_crack() -> None:
    """a/c -> 0 and a/t -> 0 in a wide plate: the deepest point of a long shallow surface crack
    is an edge crack in a half-plane, exactly 1.1215 (M1 = 1.13 gives it within 0.8 %)."""
    deepest = _surface(0.01, 1e-4, 1e-3, "depth")
    assert deepest == pytest.approx(HALF_PLANE_EDGE, rel=0.01)
    assert abs(deepest / HALF_PLANE_EDGE - 1) > 1e-3  # the fit's, not an identity


@pytest.mark.parametrize("cracks", [1, 2])
@pytest.mark.parametrize(
    ("aspect", "depth_ratio", "point"),
    [(0.2, 0.2, "bore"), (0.5, 0.6, "surface"), (1.0, 0.4, "bore"), (1.6, 0.8, "surface")],
)
def test_corner_crack_at_hole_shares_the_surface_cracks_terms(
    aspect: float, depth_ratio: float, point: str, cracks: int
) -> None:
    """The corner crack at a hole is the surface crack's M1, M2, M3, g1 and f_phi over
    sqrt(Q) (checked against easigrow above) times the hole's g2 and g3, the width's f_w and,
    for one crack, Shah's ratio: divided by those, it is that polynomial.

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


def _course_transcription(
    aspect: float, depth_ratio: float, phi: float, cracks: int, radius: float, width: float
) -> float:
    """Newman and Raju's corner crack at a hole (a/c <= 1) as Wichita State's AE 737 course
    transcribes it (ndaman/damagetolerance, examples/'Cracks Around a Hole.ipynb', cases 3
    and 4, from the course text's equations 3.1g-3.1n and 3.2), evaluated here from its
    equations: the same M1-M3, g1, g2, g3, f_phi, f_w, Q and one-crack ratio as this case,
    and one term more, g4 = 1 - 0.7 (1 - a/t)(a/c - 0.2)(1 - a/c)."""
    thickness = 0.005
    a = depth_ratio * thickness
    c, b, k = a / aspect, 0.5 * width, aspect
    m1, m2, m3 = (
        1.13 - 0.09 * k,
        -0.54 + 0.89 / (0.2 + k),
        0.5 - 1 / (0.65 + k) + 14 * (1 - k) ** 24,
    )
    g1 = 1 + (0.1 + 0.35 * depth_ratio**2) * (1 - math.sin(phi)) ** 2
    lam = 1 / (1 + (c / radius) * math.cos(0.85 * phi))
    g2 = (1 + 0.358 * lam + 1.425 * lam**2 - 1.578 * lam**3 + 2.156 * lam**4) / (1 + 0.13 * lam**2)
    g3 = (1 + 0.04 * k) * (1 + 0.1 * (1 - math.cos(phi)) ** 2) * (0.85 + 0.15 * depth_ratio**0.25)
    g4 = 1 - 0.7 * (1 - depth_ratio) * (k - 0.2) * (1 - k)
    f_phi = (k**2 * math.cos(phi) ** 2 + math.sin(phi) ** 2) ** 0.25
    f_w = math.sqrt(
        1
        / math.cos(math.pi * radius / (2 * b))
        / math.cos(
            math.pi
            * (2 * radius + cracks * c)
            / (4 * (b - c) + 2 * cracks * c)
            * math.sqrt(depth_ratio)
        )
    )
    beta = (m1 + m2 * depth_ratio**2 + m3 * depth_ratio**4) * g1 * g2 * g3 * g4 * f_phi * f_w
    beta /= math.sqrt(1 + 1.464 * k**1.65)
    if cracks == 1:
        beta *= math.sqrt(
            (4 / math.pi + a * c / (2 * thickness * radius))
            / (4 / math.pi + a * c / (thickness * radius))
        )
    return beta


@pytest.mark.parametrize("cracks", [1, 2])
@pytest.mark.parametrize("point", ["bore", "surface"])
@pytest.mark.parametrize(
    ("aspect", "depth_ratio"), [(0.2, 0.4), (0.5, 0.2), (0.6, 0.5), (1.0, 0.3), (1.0, 0.7)]
)
def test_corner_crack_at_hole_against_a_course_transcription(
    aspect: float, depth_ratio: float, point: str, cracks: int
) -> None:
    """A second, independent transcription of the corner crack at a hole (a/c <= 1): it agrees
    with this case to rounding where its extra term g4 is 1 (a/c = 0.2 or 1), which checks g2,
    g3, f_w and the one-crack ratio; between, the two differ by exactly g4, which the
    course's equations carry and TM 83200 as this case quotes it does not (this case 9.8 %
    above them at a/c = 0.6, a/t = 0.2; 12.6 % at most, a/c = 0.6, a/t -> 0).  Which is right
    is not settled here: the course names no source for g4, and neither TM 83200 nor Newman
    and Raju's later TM 85793 (1984) could be read (docs/api.md)."""
    thickness, radius, width = 0.005, 0.004, 0.5
    phi = 0.5 * math.pi if point == "bore" else 0.0
    case = CornerCrackAtHole(2 * radius, thickness, width, aspect, cracks, point)  # type: ignore[arg-type]
    ours = float(case.beta(np.array([depth_ratio * thickness]))[0])
    course = _course_transcription(aspect, depth_ratio, phi, cracks, radius, width)
    g4 = 1 - 0.7 * (1 - depth_ratio) * (aspect - 0.2) * (1 - aspect)
    assert ours * g4 == pytest.approx(course, rel=1e-12)
    if aspect in (0.2, 1.0):
        assert ours == pytest.approx(course, rel=1e-12)
    else:
        assert abs(ours / course - 1) > 0.05


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
