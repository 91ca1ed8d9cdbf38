"""The NASGRO crack growth equation's threshold and fracture terms, and Newman's closure function.

    da/dN = C [((1 - f) / (1 - R)) dK]**n (1 - dK_th / dK)**p / (1 - K_max / K_c)**q

f = K_op / K_max is Newman's crack opening function of R, the constraint factor alpha and
S_max / sigma_0 (the maximum stress over the flow stress):

    A0 = (0.825 - 0.34 alpha + 0.05 alpha**2) cos(pi/2 S_max/sigma_0)**(1/alpha)
    A1 = (0.415 - 0.071 alpha) S_max/sigma_0,  A3 = 2 A0 + A1 - 1,  A2 = 1 - A0 - A1 - A3
    f = max(R, A0 + A1 R + A2 R**2 + A3 R**3)   for R >= 0
    f = A0 + A1 R                                for -2 <= R < 0
    f = A0 - 2 A1                                for R < -2

and the threshold, for the long cracks a structure is inspected for (its small-crack factor
sqrt(a / (a + a_0)), a_0 ~ 38 um, is 0.996 or more from a 5 mm crack on, so it is left out):

    dK_th = dK_0 / [(1 - f) / ((1 - A0) (1 - R))]**(1 + C_th R)

with C_th = C_th+ for R >= 0 and C_th- below.  Source read: the NASGRO implementation of
easigrow (github.com/needsglasses/easigrow, src/dadn.rs, `impl DaDn for Nasgro`), which cites
J. A. Harter, AFGROW Users Guide and Technical Manual, AFRL-VA-WP-TR-1999-3016, 1999; the
closure function agrees with a second implementation read (a `nasgro.js` of the code corpus,
unattributed), whose threshold is written differently (dK_1 [(1 - f) / (1 - A0)]**(1 + C_th R)),
so the threshold here is the cited one.

At R = 0, f = A0, dK_th = dK_0 and K_max = dK: the equation is C (1 - A0)**n dK**n times the
two terms, which is what a march steps for one cycle of a flight's damage-equivalent range
(model.growth_laws).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from numba import njit
from torch import Tensor

from model.fast_march_math import log, power_of_log


@dataclass(frozen=True)
class NasgroTerms:
    """The NASGRO constants besides C and n (SI: MPa sqrt(m)): the threshold dK_0 at R = 0,
    the fracture toughness K_c, the exponents p and q, Newman's alpha and S_max/sigma_0, and
    the threshold's C_th+ (R >= 0) and C_th- (R < 0).  Raises ValueError for a value outside
    what the equation allows."""

    threshold_mpa_sqrt_m: float
    toughness_mpa_sqrt_m: float
    p: float
    q: float
    alpha: float
    smax_on_flow_stress: float
    cth_plus: float = 0.0
    cth_minus: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.threshold_mpa_sqrt_m < self.toughness_mpa_sqrt_m:
            raise ValueError("threshold_mpa_sqrt_m must lie in [0, toughness_mpa_sqrt_m)")
        if not (self.p >= 0.0 and self.q >= 0.0):
            raise ValueError(f"p and q must be >= 0, got {self.p} and {self.q}")
        if not 0.0 <= self.smax_on_flow_stress < 1.0:
            raise ValueError(
                f"smax_on_flow_stress must lie in [0, 1), got {self.smax_on_flow_stress}"
            )
        if not (self.alpha > 0.0 and 0.0 <= self.closure_coefficients()[0] < 1.0):
            raise ValueError(f"alpha must be > 0 with Newman's A0 in [0, 1), got {self.alpha}")

    def closure_coefficients(self) -> tuple[float, float, float, float]:
        """Newman's A0, A1, A2, A3 (module docstring)."""
        alpha, ratio = self.alpha, self.smax_on_flow_stress
        a0 = (0.825 - 0.34 * alpha + 0.05 * alpha**2) * math.cos(0.5 * math.pi * ratio) ** (
            1.0 / alpha
        )
        a1 = (0.415 - 0.071 * alpha) * ratio
        a3 = 2.0 * a0 + a1 - 1.0
        return a0, a1, 1.0 - a0 - a1 - a3, a3


def opening_ratio(load_ratio: Tensor, terms: NasgroTerms) -> Tensor:
    """Newman's f = K_op / K_max at each load ratio R (module docstring)."""
    a0, a1, a2, a3 = terms.closure_coefficients()
    r = load_ratio
    positive = torch.maximum(r, a0 + a1 * r + a2 * r**2 + a3 * r**3)
    negative = torch.where(r >= -2.0, a0 + a1 * r, torch.full_like(r, a0 - 2.0 * a1))
    return torch.where(r >= 0.0, positive, negative)


def threshold(load_ratio: Tensor, terms: NasgroTerms) -> Tensor:
    """dK_th (MPa sqrt(m)) at each R < 1, long cracks (module docstring)."""
    a0 = terms.closure_coefficients()[0]
    r = load_ratio
    cth = torch.where(r >= 0.0, terms.cth_plus, terms.cth_minus)
    base = (1.0 - opening_ratio(r, terms)) / ((1.0 - a0) * (1.0 - r))
    return terms.threshold_mpa_sqrt_m / base ** (1.0 + cth * r)


def nasgro_rate(
    stress_intensity: Tensor, load_ratio: Tensor, c: float, n: float, terms: NasgroTerms
) -> Tensor:
    """da/dN (m per cycle) of the NASGRO equation at dK (MPa sqrt(m)) and R < 1: 0 at or below
    the threshold, the dtype's largest float at or past fracture (K_max = dK / (1 - R) >= K_c:
    the crack runs away, and a march holds it; not +inf, whose product with a growth factor
    would make that factor's gradient 0 * inf = nan).  The gradient is finite everywhere (both
    ends are masked before the powers) and 0 past both ends."""
    if bool((load_ratio >= 1.0).any()):
        raise ValueError("load ratios must be < 1")
    r = load_ratio
    effective = (1.0 - opening_ratio(r, terms)) / (1.0 - r) * stress_intensity
    k_max = stress_intensity / (1.0 - r)
    dk_th = threshold(r, terms)
    above = stress_intensity > dk_th
    below = k_max < terms.toughness_mpa_sqrt_m
    growing = above & below
    # masked: the powers never see a base <= 0, so autograd never meets 0 * inf
    dk = torch.where(growing, stress_intensity, terms.toughness_mpa_sqrt_m / 2.0)
    rate = (
        c
        * torch.where(growing, effective, 1.0) ** n
        * (1.0 - torch.where(growing, dk_th, 0.0) / dk) ** terms.p
        / (1.0 - torch.where(growing, k_max, 0.0) / terms.toughness_mpa_sqrt_m) ** terms.q
    )
    runaway = torch.finfo(rate.dtype).max
    stopped = torch.where(above, torch.full_like(rate, runaway), torch.zeros_like(rate))
    return torch.where(growing, rate, stopped)


def march_terms(terms: NasgroTerms) -> np.ndarray:
    """(4,) dK_0, K_c, p, q: what the compiled march reads (`growth`, `growth_slope`)."""
    return np.array(
        [terms.threshold_mpa_sqrt_m, terms.toughness_mpa_sqrt_m, terms.p, terms.q], dtype=np.float64
    )


@njit(inline="always", error_model="numpy")
def growth(dk, c, n, terms):  # pragma: no cover - compiled
    """C' dK**n (1 - dK_0/dK)**p / (1 - dK/K_c)**q at R = 0 (C' = C (1 - A0)**n, module
    docstring): 0 at or below dK_0, +inf at or past K_c."""
    dk0, kc, p, q = terms[0], terms[1], terms[2], terms[3]
    if not dk > dk0:
        return 0.0
    if not dk < kc:
        return math.inf
    return (
        c
        * power_of_log(log(dk), n)
        * power_of_log(log(1.0 - dk0 / dk), p)
        / power_of_log(log(1.0 - dk / kc), q)
    )


@njit(inline="always", error_model="numpy")
def growth_slope(dk, rate, n, terms):  # pragma: no cover - compiled
    """d growth / d dK given growth = rate: rate (n/dK + p dK_0/(dK (dK - dK_0)) + q/(K_c - dK));
    0 where the rate is 0 or infinite (a held crack carries no gradient)."""
    dk0, kc, p, q = terms[0], terms[1], terms[2], terms[3]
    if not (dk > dk0 and dk < kc):
        return 0.0
    return rate * (n / dk + p * dk0 / (dk * (dk - dk0)) + q / (kc - dk))
