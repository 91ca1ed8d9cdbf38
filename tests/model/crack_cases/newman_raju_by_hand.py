"""Newman and Raju's surface crack (a/c <= 1) written out from Eng. Fract. Mech. 15 (1981)
185-192 for the tests' hand calculations, apart from model.crack_cases.newman_raju."""

from __future__ import annotations

import math


def surface_crack_beta(a: float, c: float, thickness: float, width: float, phi: float) -> float:
    """K / (S sqrt(pi a)) at angle phi (pi/2: the deepest point) of a front of depth a and
    half length c (a <= c):
    [M1 + M2 (a/t)**2 + M3 (a/t)**4] g f_phi f_w / sqrt(Q)."""
    k, depth = a / c, a / thickness
    assert 0 < k <= 1, k
    m1 = 1.13 - 0.09 * k
    m2 = -0.54 + 0.89 / (0.2 + k)
    m3 = 0.5 - 1 / (0.65 + k) + 14 * (1 - k) ** 24
    g = 1 + (0.1 + 0.35 * depth**2) * (1 - math.sin(phi)) ** 2
    f_phi = (k**2 * math.cos(phi) ** 2 + math.sin(phi) ** 2) ** 0.25
    f_w = 1 / math.sqrt(math.cos(math.pi * c / width * math.sqrt(depth)))
    q = 1 + 1.464 * k**1.65
    return (m1 + m2 * depth**2 + m3 * depth**4) * g * f_phi * f_w / math.sqrt(q)
