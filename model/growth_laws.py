"""Growth laws da/dN(dK, a flight's load channels, the law's constants), and how a flight's
cycles reduce to the one range the march steps with.

A law sees only its material constants (C, m, Walker's gamma, the NASGRO terms): the geometry
factor, the initial and the critical crack belong to the fleet's physics
(model.physics.ParisLaw), not to the law.  Laws are a registry (GROWTH_LAWS) read by the model
spec and the model files: Paris, Walker and NASGRO (model.nasgro).

**Why one input per flight, whatever the spectrum.**  A flight's cycles (range dS_k, load
ratio R_k, count n_k) grow the crack by the sum of their increments, and the crack changes by
less than 1e-3 of itself within a flight, so the per-flight Euler step holds a over the
flight:  da = f * sum_k n_k * law(dK(dS_k, a), R_k).  Every kernel of model.cells is the
physics dK = F dS sqrt(pi a) times a correction, and Walker's law is a power of dK / (1 - R)
**(1 - gamma), so for the physics that sum is one cycle of the flight's damage-equivalent
range

    dS_eq = [sum_k n_k (dS_k (1 - R_k)**(gamma - 1))**m] ** (1/m),

exactly (`equivalent_range`).  Every march (the compiled one included) therefore steps one
cycle of dS_eq per flight, at the speed of today's single-range input, and a law's exponents
enter only through dS_eq, computed once per history and law (model.integrate.LoadHistory
.for_law).  The residual kernel's correction reads dS_eq as the flight's severity: that is the
one approximation (a network correction that differs between a flight's cycles is averaged into
one factor), measured in benchmarks/spectra.py.  Walker's gamma, like C and m, is fitted by the
physics alone in closed form (model.paris_calibration), where dS_eq**m is the flight's damage.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import torch
from numba import njit
from torch import Tensor

from model.fast_march_math import power
from model.nasgro import NasgroTerms, march_terms, nasgro_rate, opening_ratio


@dataclass(frozen=True)
class GrowthConstants:
    """A growth law's material constants (SI: m per cycle, MPa sqrt(m)): C, m and Walker's
    gamma (1: the rate does not depend on R, Paris' law), and the NASGRO law's other terms
    (model.nasgro; read by that law only, which C and m are C and n of)."""

    c: float
    m: float
    gamma: float = 1.0
    nasgro: NasgroTerms | None = None
    # Walker's gamma for cycles at R < 0 (None: `gamma` there too); 0 ignores the compressive
    # part of a cycle (its rate a power of K_max alone), the practice Dowling recommends for
    # R < 0 (N. E. Dowling, Mechanical Behavior of Materials, 4th ed. 2013, sec. 11.4)
    gamma_below_zero: float | None = None


class GrowthLaw:
    """da/dN of one cycle, and the damage-equivalent range of a flight's cycles.  A subclass
    with a `name` registers itself in GROWTH_LAWS."""

    name: ClassVar[str] = ""
    uses_gamma: ClassVar[bool] = False  # whether gamma is one of its constants
    # whether model.paris_calibration can fit it (its damage a power of the range)
    calibrated: ClassVar[bool] = True

    def __init_subclass__(cls, **kwargs: object) -> None:
        super().__init_subclass__(**kwargs)
        if cls.name:
            if cls.name in GROWTH_LAWS:
                raise ValueError(f"growth law {cls.name!r} is registered twice")
            GROWTH_LAWS[cls.name] = cls()

    def gamma(self, constants: GrowthConstants) -> float:
        """The exponent of (1 - R) the law uses (1: none)."""
        return 1.0

    def cycle_weight(self, load_ratio: np.ndarray, constants: GrowthConstants) -> np.ndarray | None:
        """w(R) with a cycle (dS, R) as damaging as one of w dS at R = 0, for a law whose R
        effect is not a power of (1 - R) (the NASGRO law's closure), else None (gamma's power,
        computed inside the compiled sums as before)."""
        return None

    def check(self, constants: GrowthConstants) -> None:
        """Raises ValueError where `constants` lack what this law needs."""

    def weight_terms(self, constants: GrowthConstants) -> tuple[float, ...]:
        """What `cycle_weight` depends on besides R (a reduction's cache key,
        model.integrate): nothing for a power of (1 - R)."""
        return ()

    def march_constants(self, constants: GrowthConstants) -> tuple[float, float, np.ndarray]:
        """(C, m, terms) the compiled march steps with, model.fast_march: terms is empty for
        C dK**m, else the NASGRO terms (model.nasgro.march_terms)."""
        return float(constants.c), float(constants.m), np.zeros(0)

    def __call__(
        self, stress_intensity: Tensor, flight: dict[str, Tensor], constants: GrowthConstants
    ) -> Tensor:
        """da/dN in m per cycle from dK (MPa sqrt(m)) and the flight's channels at this step
        (`load_ratio`, where the flight has one; an absent R is 0).  A negative dK (only a
        network makes one) grows nothing."""
        rate = constants.c * stress_intensity.clamp_min(0.0) ** constants.m
        gamma = self.gamma(constants)
        ratio = flight.get("load_ratio")
        if ratio is None:
            return rate
        if self.uses_gamma and constants.gamma_below_zero is not None:
            below = torch.as_tensor(constants.gamma_below_zero, dtype=ratio.dtype)
            exponent = torch.where(ratio < 0, below, torch.as_tensor(gamma, dtype=ratio.dtype))
            return rate * (1.0 - ratio) ** ((exponent - 1.0) * constants.m)
        if gamma == 1.0:
            return rate
        return rate * (1.0 - ratio) ** ((gamma - 1.0) * constants.m)

    def equivalent_range(self, cycles: CycleSpectrum, constants: GrowthConstants) -> Tensor:
        """(aircraft, flights) dS_eq of each flight's cycles (module docstring), MPa; 0 where a
        flight has no cycle.  A numba loop per flight, so each flight's value does not depend
        on the batch it is computed in (forecasts are batch-invariant)."""
        ranges, ratios = _array(cycles.stress_range_mpa), _array(cycles.load_ratio)
        weight = self.cycle_weight(ratios, constants)
        out = _equivalent_ranges(
            ranges if weight is None else ranges * weight,
            ratios,
            _array(cycles.count),
            float(constants.m),
            float(self.gamma(constants)),
        )
        return torch.from_numpy(out)

    def flights_equivalent_range(
        self, table: np.ndarray, starts: np.ndarray, constants: GrowthConstants
    ) -> np.ndarray:
        """(flights,) dS_eq of flights whose cycles lie back to back: `table` (cycles, 3) of
        range, load ratio and count, flight f's rows starts[f]:starts[f + 1] (a cycle file as
        read, model.spectrum_files.CycleTable); the same sums in the same order as
        `equivalent_range`, without padding every flight to the longest."""
        table = np.ascontiguousarray(table, dtype=np.float64)
        weight = self.cycle_weight(table[:, 1], constants)
        if weight is not None:
            table = np.column_stack((table[:, 0] * weight, table[:, 1], table[:, 2]))
        return _run_equivalent_ranges(
            table,
            np.asarray(starts, dtype=np.int64),
            float(constants.m),
            float(self.gamma(constants)),
        )

    def flight_damage(self, cycles: CycleSpectrum, m: Tensor, gamma: Tensor) -> Tensor:
        """(aircraft, flights) dS_eq**m, differentiable in m and gamma: the exact sum the
        calibration's binned one approximates (model.binned_damage)."""
        ranges = cycles.stress_range_mpa.to(torch.float64)
        count = cycles.count.to(torch.float64)
        flown = (ranges > 0) & (count > 0)
        exponent = m * torch.log(ranges.clamp_min(1e-300))
        if self.uses_gamma:
            exponent = exponent + m * (gamma - 1.0) * torch.log1p(-cycles.load_ratio.double())
        return torch.where(flown, count * torch.exp(exponent), 0.0).sum(dim=-1)


GROWTH_LAWS: dict[str, GrowthLaw] = {}


class Paris(GrowthLaw):
    """da/dN = C max(dK, 0)**m, whatever the load ratio."""

    name = "paris"


class Walker(GrowthLaw):
    """da/dN = C [max(dK, 0) / (1 - R)**(1 - gamma)]**m (Walker 1970); gamma = 1 is Paris.
    Below R = 0 the exponent is `gamma_below_zero` where the constants give one (0: the
    compressive part ignored, Dowling's practice), else gamma as above R = 0 (the default,
    as before; a fully reversed cycle of 2024-T3 then weighs 5.4x what gamma = 0 gives).  No
    closure model: the NASGRO threshold and fracture terms are not part of it.

    The R < 0 exponent enters every reduction as a cycle weight, w(R) = (1 - R)**(gamma_- -
    gamma) below R = 0 and 1 above, so the compiled sums (`equivalent_range`) and the torch
    rate agree, and the calibration, which learns gamma, reads those cycles as their
    equivalents at R = 0 (`fixed_below_zero`)."""

    name = "walker"
    uses_gamma = True

    def gamma(self, constants: GrowthConstants) -> float:
        return float(constants.gamma)

    def cycle_weight(self, load_ratio: np.ndarray, constants: GrowthConstants) -> np.ndarray | None:
        below = constants.gamma_below_zero
        if below is None:
            return None
        ratio = np.asarray(load_ratio, dtype=np.float64)
        return np.where(ratio < 0, (1.0 - ratio) ** (below - constants.gamma), 1.0)

    def weight_terms(self, constants: GrowthConstants) -> tuple[float, ...]:
        below = constants.gamma_below_zero
        return () if below is None else (float(below),)

    def check(self, constants: GrowthConstants) -> None:
        below = constants.gamma_below_zero
        if below is not None and not 0.0 <= below <= 1.0:
            raise ValueError(f"gamma_below_zero must lie in [0, 1], got {below}")


def fixed_below_zero(cycles: CycleSpectrum, constants: GrowthConstants) -> CycleSpectrum:
    """The cycles with each one at R < 0 replaced by its equivalent at R = 0 under
    gamma_below_zero, dS (1 - R)**(gamma_- - 1): its damage then no longer depends on the
    gamma a calibration learns above R = 0.  Unchanged without gamma_below_zero."""
    below = constants.gamma_below_zero
    if below is None:
        return cycles
    ratio = cycles.load_ratio.to(torch.float64)
    negative = ratio < 0
    ranges = cycles.stress_range_mpa.to(torch.float64)
    mapped = torch.where(negative, ranges * (1.0 - ratio) ** (below - 1.0), ranges)
    return CycleSpectrum(mapped, torch.where(negative, 0.0, ratio), cycles.count)


class Nasgro(GrowthLaw):
    """da/dN = C [((1 - f) / (1 - R)) dK]**n (1 - dK_th / dK)**p / (1 - K_max / K_c)**q, the
    NASGRO equation with Newman's closure f and the NASGRO threshold (model.nasgro, where the
    equations and their source are); C and n are the constants' c and m, the rest
    `constants.nasgro`.

    A flight's cycles reduce as for the other laws, each weighted by the closure,
    w(R) = (1 - f(R)) / ((1 - R) (1 - A0)), so the Paris region of the equation is summed
    exactly; the threshold and fracture terms then act on that one equivalent cycle at R = 0.
    For a flight of one cycle at R = 0 (today's single range) that is the equation itself; for
    a spectrum it is an approximation: a cycle below the threshold still counts in the sum.
    C and n are fixed, not calibrated (model.paris_calibration fits laws whose damage is a
    power of the range); the per-tail growth factor still scales the rate."""

    name = "nasgro"
    calibrated = False

    def __call__(
        self, stress_intensity: Tensor, flight: dict[str, Tensor], constants: GrowthConstants
    ) -> Tensor:
        terms = _terms(constants)
        ratio = flight.get("load_ratio")
        if ratio is None:
            ratio = torch.zeros_like(stress_intensity)
        return nasgro_rate(stress_intensity, ratio, constants.c, constants.m, terms)

    def cycle_weight(self, load_ratio: np.ndarray, constants: GrowthConstants) -> np.ndarray:
        terms = _terms(constants)
        ratio = torch.from_numpy(np.asarray(load_ratio, dtype=np.float64))
        a0 = terms.closure_coefficients()[0]
        weight = (1.0 - opening_ratio(ratio, terms)) / ((1.0 - ratio) * (1.0 - a0))
        return weight.numpy()

    def check(self, constants: GrowthConstants) -> None:
        _terms(constants)

    def weight_terms(self, constants: GrowthConstants) -> tuple[float, ...]:
        terms = _terms(constants)
        return (terms.alpha, terms.smax_on_flow_stress)

    def march_constants(self, constants: GrowthConstants) -> tuple[float, float, np.ndarray]:
        terms = _terms(constants)
        a0 = terms.closure_coefficients()[0]
        return (
            float(constants.c * (1.0 - a0) ** constants.m),
            float(constants.m),
            march_terms(terms),
        )


def _terms(constants: GrowthConstants) -> NasgroTerms:
    if constants.nasgro is None:
        raise ValueError(
            "the nasgro growth law needs its terms (dK_0, K_c, p, q, alpha, S_max/sigma_0): "
            "a material whose row has them (a user's materials file: the shipped table has none)"
        )
    return constants.nasgro


@dataclass(frozen=True)
class CycleSpectrum:
    """Every flight's cycles, zero-padded to the most cycles of any flight.

    stress_range_mpa, load_ratio, count: (aircraft, flights, cycles); count may be 0.5 for the
    half cycles of a rainflow count; a padded cycle has count 0.
    """

    stress_range_mpa: Tensor
    load_ratio: Tensor
    count: Tensor

    def __post_init__(self) -> None:
        shape = self.stress_range_mpa.shape
        if len(shape) != 3:
            raise ValueError("cycle channels must be (aircraft, flights, cycles)")
        if self.load_ratio.shape != shape or self.count.shape != shape:
            raise ValueError("stress_range_mpa, load_ratio and count must have the same shape")

    def pick(self, aircraft: Tensor | slice, flights: int | None = None) -> CycleSpectrum:
        """The given aircraft (and their first `flights` flights)."""
        cut = slice(None) if flights is None else slice(None, flights)
        return CycleSpectrum(
            self.stress_range_mpa[aircraft, cut],
            self.load_ratio[aircraft, cut],
            self.count[aircraft, cut],
        )


def _array(values: Tensor) -> np.ndarray:
    return values.detach().to(torch.float64).contiguous().numpy()


@njit(cache=True, error_model="numpy")
def _equivalent_ranges(ranges, ratios, counts, m, gamma):  # pragma: no cover - compiled
    """dS_eq (aircraft, flights) = [sum_k n_k (dS_k (1 - R_k)**(gamma - 1))**m]**(1/m)."""
    n, flights, cycles = ranges.shape
    out = np.zeros((n, flights))
    for i in range(n):
        for t in range(flights):
            total = 0.0
            for k in range(cycles):
                s, r, count = ranges[i, t, k], ratios[i, t, k], counts[i, t, k]
                if s > 0.0 and count > 0.0:
                    effective = s if gamma == 1.0 else s * power(1.0 - r, gamma - 1.0)
                    total += count * power(effective, m)
            out[i, t] = power(total, 1.0 / m) if total > 0.0 else 0.0
    return out


@njit(cache=True, error_model="numpy")
def _run_equivalent_ranges(table, starts, m, gamma):  # pragma: no cover - compiled
    """dS_eq (flights,) of flights stored back to back (_equivalent_ranges' sums)."""
    flights = len(starts) - 1
    out = np.zeros(flights)
    for f in range(flights):
        total = 0.0
        for k in range(starts[f], starts[f + 1]):
            s, r, count = table[k, 0], table[k, 1], table[k, 2]
            if s > 0.0 and count > 0.0:
                effective = s if gamma == 1.0 else s * power(1.0 - r, gamma - 1.0)
                total += count * power(effective, m)
        out[f] = power(total, 1.0 / m) if total > 0.0 else 0.0
    return out
