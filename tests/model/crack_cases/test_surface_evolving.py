"""The surface crack whose shape evolves as it grows: its path against the two-point growth
law and Newman and Raju's converged shape, and its critical crack by hand at three stresses
along a path integrated here apart from the case's own (scipy's adaptive Runge-Kutta in a,
against the case's fixed-step RK4 in ln a)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from model.crack_cases.residual_strength import Toughness, critical_crack
from model.crack_cases.surface import SurfaceCrack
from tests.model.crack_cases.hand import SIGMA_Y, bisect, by_criterion, first_root
from tests.model.crack_cases.newman_raju_by_hand import surface_crack_beta


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


@pytest.mark.parametrize("point", ["depth", "surface"])
def test_critical_evolving_surface_crack_by_hand_at_three_stresses(point: str) -> None:
    """A long shallow crack (a/c = 0.3 at 0.5 mm) in a 40 x 10 mm section, m = 3, K_c 30.  By
    hand: the half length c(a) from dc/da = (F(phi = 0) / F(phi = pi/2))**3 (Newman and Raju
    written out, integrated to 1e-11), then the first crack where K = F S sqrt(pi a) reaches
    K_c at the case's point (a uniform scan, bisected) and where the net section yields,
    S W t = sigma_y (W t - pi a c(a) / 2) (bisection).  At 100 MPa the crack reaches the far
    face first, at 200 MPa it fractures, at 340 MPa the net section yields."""
    thickness, width, start_aspect, start_depth, m, k_c = 0.01, 0.04, 0.3, 0.0005, 3.0, 30.0
    phi = 0.5 * math.pi if point == "depth" else 0.0
    case = SurfaceCrack(
        thickness,
        width,
        start_aspect,
        point,
        growth_exponent=m,
        shape_at_depth_m=start_depth,  # type: ignore[arg-type]
    )

    def slope(a: float, c: np.ndarray) -> list[float]:
        at_surface = surface_crack_beta(a, float(c[0]), thickness, width, 0.0)
        at_depth = surface_crack_beta(a, float(c[0]), thickness, width, 0.5 * math.pi)
        return [(at_surface / at_depth) ** m]

    path = solve_ivp(
        slope,
        (start_depth, thickness),
        [start_depth / start_aspect],
        rtol=1e-11,
        atol=1e-15,
        dense_output=True,
    )
    assert path.success

    def half_length(a: float) -> float:
        return float(path.sol(a)[0])

    # the path the case states: from the long shallow start towards a/c ~ 0.8, and a half
    # length that stays inside the width's half (so the crack runs to the far face, a = t)
    assert 0.7 < thickness / half_length(thickness) < 0.9
    assert half_length(thickness) < 0.5 * width
    extent = thickness
    toughness = Toughness(k_c, "K_c", SIGMA_Y)
    for stress, criterion in (
        (100.0, "extent"),
        (200.0, "fracture"),
        (340.0, "net_section_yield"),
    ):

        def k_less_kc(a: float, s: float = stress) -> float:
            beta = surface_crack_beta(a, half_length(a), thickness, width, phi)
            return beta * s * math.sqrt(math.pi * a) - k_c

        def net_less_yield(a: float, s: float = stress) -> float:
            net = width * thickness - 0.5 * math.pi * a * half_length(a)
            return s * width * thickness / net - SIGMA_Y

        fracture = first_root(k_less_kc, start_depth, extent * (1 - 1e-9))
        high = extent * (1 - 1e-9)
        net = bisect(net_less_yield, start_depth, high) if net_less_yield(high) > 0 else math.inf
        want, governs = by_criterion(fracture, net, extent)
        got = critical_crack(case, stress, toughness, start_depth)
        assert (got.criterion, governs) == (criterion, criterion), stress
        # measured within 2.7e-6: the case reads its path linearly between RK4 nodes
        assert got.crack_length_m == pytest.approx(want, rel=1e-5), stress
