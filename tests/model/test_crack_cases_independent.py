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
