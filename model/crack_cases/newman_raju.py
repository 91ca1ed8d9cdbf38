"""The terms Newman and Raju's surface- and corner-crack equations share.

Source: J. C. Newman Jr. and I. S. Raju, Stress-intensity factor equations for cracks in
three-dimensional finite bodies, NASA TM 83200 (1981), also ASTM STP 791 (1983) I-238, and
Eng. Fract. Mech. 15 (1981) 185-192 for the surface crack.  k = a/c is the crack's aspect
ratio (a float, or an array of one per crack where the shape evolves), phi the parametric
angle of the crack front (pi/2: the deepest point, a; 0: the surface point, c).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def shape_factor(aspect: ArrayLike) -> np.ndarray:
    """Q = 1 + 1.464 k**1.65 (k <= 1; (c/a)**1.65 beyond): the square of the complete
    elliptic integral E(k'), to within 0.13 %."""
    k = np.asarray(aspect, dtype=np.float64)
    k = np.where(k <= 1.0, k, 1.0 / k)
    return 1.0 + 1.464 * k**1.65


def angle_factor(aspect: ArrayLike, phi: float) -> np.ndarray:
    """f_phi = (k**2 cos**2 phi + sin**2 phi)**(1/4) (k <= 1), ((1/k)**2 sin**2 + cos**2)**(1/4)
    beyond."""
    k = np.asarray(aspect, dtype=np.float64)
    sin2, cos2 = np.sin(phi) ** 2, np.cos(phi) ** 2
    return np.where(k <= 1.0, (k**2 * cos2 + sin2) ** 0.25, (sin2 / k**2 + cos2) ** 0.25)


def depth_terms(aspect: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """M1, M2, M3 of the surface crack: beta's polynomial in a/t is M1 + M2 (a/t)**2 + M3
    (a/t)**4."""
    k = np.asarray(aspect, dtype=np.float64)
    inverse = 1.0 / k
    short = k <= 1.0
    m1 = np.where(short, 1.13 - 0.09 * k, np.sqrt(inverse) * (1.0 + 0.04 * inverse))
    m2 = np.where(short, -0.54 + 0.89 / (0.2 + k), 0.2 * inverse**4)
    m3 = np.where(short, 0.5 - 1.0 / (0.65 + k) + 14.0 * np.abs(1.0 - k) ** 24, -0.11 * inverse**4)
    return m1, m2, m3


def surface_term(aspect: ArrayLike, depth_ratio: np.ndarray, phi: float) -> np.ndarray:
    """g = 1 + (0.1 + 0.35 (a/t)**2) (1 - sin phi)**2 (k <= 1; 0.35 (c/a) (a/t)**2 beyond)."""
    k = np.asarray(aspect, dtype=np.float64)
    weight = np.where(k <= 1.0, 0.35, 0.35 / k)
    return 1.0 + (0.1 + weight * depth_ratio**2) * (1.0 - np.sin(phi)) ** 2
