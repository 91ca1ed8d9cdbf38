"""The terms Newman and Raju's surface- and corner-crack equations share.

Source: J. C. Newman Jr. and I. S. Raju, Stress-intensity factor equations for cracks in
three-dimensional finite bodies, NASA TM 83200 (1981), also ASTM STP 791 (1983) I-238, and
Eng. Fract. Mech. 15 (1981) 185-192 for the surface crack.  k = a/c is the crack's aspect
ratio, phi the parametric angle of the crack front (pi/2: the deepest point, a; 0: the
surface point, c).
"""

from __future__ import annotations

import numpy as np


def shape_factor(aspect: float) -> float:
    """Q = 1 + 1.464 k**1.65 (k <= 1; (c/a)**1.65 beyond): the square of the complete
    elliptic integral E(k'), to within 0.13 %."""
    k = aspect if aspect <= 1.0 else 1.0 / aspect
    return 1.0 + 1.464 * k**1.65


def angle_factor(aspect: float, phi: float) -> float:
    """f_phi = (k**2 cos**2 phi + sin**2 phi)**(1/4) (k <= 1), ((1/k)**2 sin**2 + cos**2)**(1/4)
    beyond."""
    if aspect <= 1.0:
        return float((aspect**2 * np.cos(phi) ** 2 + np.sin(phi) ** 2) ** 0.25)
    return float((np.sin(phi) ** 2 / aspect**2 + np.cos(phi) ** 2) ** 0.25)


def depth_terms(aspect: float) -> tuple[float, float, float]:
    """M1, M2, M3 of the surface crack: beta's polynomial in a/t is M1 + M2 (a/t)**2 + M3
    (a/t)**4."""
    k = aspect
    if k <= 1.0:
        m1 = 1.13 - 0.09 * k
        m2 = -0.54 + 0.89 / (0.2 + k)
        m3 = 0.5 - 1.0 / (0.65 + k) + 14.0 * (1.0 - k) ** 24
        return m1, m2, m3
    inverse = 1.0 / k
    return np.sqrt(inverse) * (1.0 + 0.04 * inverse), 0.2 * inverse**4, -0.11 * inverse**4


def surface_term(aspect: float, depth_ratio: np.ndarray, phi: float) -> np.ndarray:
    """g = 1 + (0.1 + 0.35 (a/t)**2) (1 - sin phi)**2 (k <= 1; 0.35 (c/a) (a/t)**2 beyond)."""
    weight = 0.35 if aspect <= 1.0 else 0.35 / aspect
    return 1.0 + (0.1 + weight * depth_ratio**2) * (1.0 - np.sin(phi)) ** 2
