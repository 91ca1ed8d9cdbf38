"""The critical crack and the residual strength of a crack case.

A cracked section fails where the first of two criteria is met:
    fracture:           K_max = beta(a) S_max sqrt(pi a) reaches the toughness K_c (K_IC),
    net-section yield:  S_max A_gross / A_net(a) reaches the yield strength sigma_y,
so a_crit is the smaller of the two cracks, and the residual strength at a crack the smaller
of K_c / (beta sqrt(pi a)) and sigma_y A_net / A_gross.  Both read the case's closed form (not
its table).  Which toughness applies: a section thinner than ASTM E399's plane-strain size
2.5 (K_IC / sigma_y)**2 fractures under plane stress at K_c where the material has one; a
thicker one, or a material without K_c, at K_IC (the lower, conservative value).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.optimize import brentq

from model.crack_cases.base import CrackCase, mm

# "extent": the crack reaches the end of its case (the far face of a surface or corner crack,
# the edge of the section) before either criterion
Criterion = Literal["fracture", "net_section_yield", "extent"]
# ASTM E399's thickness for plane strain, in units of (K_IC / sigma_y)**2
PLANE_STRAIN_SIZE = 2.5
# cracks scanned between a0 and the case's extent before the root is refined (log-spaced)
_SCAN = 2048


@dataclass(frozen=True)
class Toughness:
    """The toughness a section fractures at and why (`kind`: 'K_c' plane stress, 'K_IC', or
    'given' by the location itself), with the yield strength for net-section yield (None: not
    checked)."""

    fracture_toughness_mpa_sqrt_m: float
    kind: Literal["K_c", "K_IC", "given"]
    yield_strength_mpa: float | None

    def __post_init__(self) -> None:
        if not self.fracture_toughness_mpa_sqrt_m > 0:
            raise ValueError(
                "fracture_toughness_mpa_sqrt_m must be > 0, got "
                f"{self.fracture_toughness_mpa_sqrt_m!r}"
            )
        if self.yield_strength_mpa is not None and not self.yield_strength_mpa > 0:
            raise ValueError(f"yield_strength_mpa must be > 0, got {self.yield_strength_mpa!r}")


def toughness_for(
    k_ic_mpa_sqrt_m: float,
    k_c_mpa_sqrt_m: float | None,
    yield_strength_mpa: float | None,
    thickness_m: float | None,
) -> Toughness:
    """The toughness of a section of this thickness (module docstring): K_c below the
    plane-strain size where both K_c and the yield strength are known (or the thickness is
    unknown and K_c given), else K_IC."""
    if k_c_mpa_sqrt_m is None:
        return Toughness(k_ic_mpa_sqrt_m, "K_IC", yield_strength_mpa)
    if thickness_m is not None and yield_strength_mpa is not None:
        plane_strain_m = PLANE_STRAIN_SIZE * (k_ic_mpa_sqrt_m / yield_strength_mpa) ** 2
        if thickness_m >= plane_strain_m:
            return Toughness(k_ic_mpa_sqrt_m, "K_IC", yield_strength_mpa)
    return Toughness(k_c_mpa_sqrt_m, "K_c", yield_strength_mpa)


@dataclass(frozen=True)
class CriticalCrack:
    """a_crit (m) and the criterion that sets it (Criterion); fracture_crack_m and yield_crack_m are each
    criterion's own crack (None: not reached before the section is severed, or not checked);
    `warning` where a_crit lies past the case's validity range (lengths in mm, as the
    reader's)."""

    crack_length_m: float
    criterion: Criterion
    fracture_crack_m: float | None
    yield_crack_m: float | None
    warning: str | None


def critical_crack(
    case: CrackCase, max_stress_mpa: float, toughness: Toughness, initial_crack_m: float
) -> CriticalCrack:
    """The smallest crack above initial_crack_m at which the section fails under
    max_stress_mpa (module docstring).  Raises ValueError naming max_stress_mpa where the
    section fails at the initial crack already, or initial_crack_m where it is not inside the
    case."""
    if not max_stress_mpa > 0:
        raise ValueError(f"max_stress_mpa must be > 0, got {max_stress_mpa!r}")
    extent = case.extent_m()
    if not 0 < initial_crack_m < extent:
        raise ValueError(f"initial_crack_m must lie in (0, {extent:g}) m, got {initial_crack_m!r}")
    strength = residual_strength(case, initial_crack_m, toughness)
    if strength.stress_mpa <= max_stress_mpa:
        raise ValueError(
            f"max_stress_mpa ({max_stress_mpa:g} MPa) fails the section at the initial crack "
            f"already ({strength.criterion}, residual strength {strength.stress_mpa:.4g} MPa)"
        )
    k_c = toughness.fracture_toughness_mpa_sqrt_m

    def fracture(a: np.ndarray) -> np.ndarray:
        return case.beta(a) * max_stress_mpa * np.sqrt(np.pi * a) - k_c

    fracture_crack = _first_root(fracture, initial_crack_m, extent)
    yield_crack = None
    if (
        toughness.yield_strength_mpa is not None
        and case.net_section_factor(np.array([initial_crack_m])) is not None
    ):
        sigma_y = toughness.yield_strength_mpa

        def net_yield(a: np.ndarray) -> np.ndarray:
            factor = case.net_section_factor(a)
            assert factor is not None
            return max_stress_mpa * factor - sigma_y

        yield_crack = _first_root(net_yield, initial_crack_m, extent)
    found = ((fracture_crack, "fracture"), (yield_crack, "net_section_yield"))
    reached = [(a, c) for a, c in found if a is not None]
    if not reached:
        crack, criterion = extent, "extent"
    else:
        crack, criterion = min(reached, key=lambda pair: pair[0])
    validity = case.validity()
    warning = None
    if crack > validity.crack_length_m:
        warning = (
            f"a_crit = {mm(crack)} lies past the case's validity range, which ends at "
            f"{case.validity_said()}"
        )
    return CriticalCrack(crack, criterion, fracture_crack, yield_crack, warning)  # type: ignore[arg-type]


@dataclass(frozen=True)
class ResidualStrength:
    """The stress (MPa) the cracked section carries, and the criterion that sets it."""

    stress_mpa: float
    criterion: Criterion

    def margin_over(self, limit_stress_mpa: float) -> float:
        """Residual strength over the limit stress, less one (0.2: 20 % above the limit)."""
        return self.stress_mpa / limit_stress_mpa - 1.0


def residual_strength(
    case: CrackCase, crack_length_m: float, toughness: Toughness
) -> ResidualStrength:
    """min(K_c / (beta(a) sqrt(pi a)), sigma_y A_net / A_gross) at crack_length_m (m)."""
    a = np.array([crack_length_m], dtype=np.float64)
    by_fracture = toughness.fracture_toughness_mpa_sqrt_m / float(
        case.beta(a)[0] * np.sqrt(np.pi * crack_length_m)
    )
    factor = case.net_section_factor(a)
    if toughness.yield_strength_mpa is None or factor is None:
        return ResidualStrength(by_fracture, "fracture")
    by_yield = toughness.yield_strength_mpa / float(factor[0])
    if by_yield < by_fracture:
        return ResidualStrength(by_yield, "net_section_yield")
    return ResidualStrength(by_fracture, "fracture")


def _first_root(
    function: Callable[[np.ndarray], np.ndarray], start_m: float, extent_m: float
) -> float | None:
    """The smallest a in (start, extent) where function(a) (vectorised) turns >= 0, refined
    by Brent's method on the first bracketing interval of a log-spaced scan; None if never."""
    grid = np.geomspace(start_m, extent_m * (1.0 - 1e-9), _SCAN)
    with np.errstate(invalid="ignore", divide="ignore"):
        values = function(grid)
    crossed = np.flatnonzero(values >= 0)
    if not len(crossed):
        return None
    k = int(crossed[0])
    if k == 0:
        return float(start_m)
    return float(
        brentq(
            lambda a: float(function(np.array([a]))[0]),
            grid[k - 1],
            grid[k],
            xtol=1e-15,
            rtol=1e-13,
        )
    )
