"""A location's crack case (model.crack_cases): its beta(a) as the march reads it, and the
critical crack and residual strength from its limit stress and its material's strengths.

Kept apart from app.services.records.locations, which stores the entry: this module only reads it.
What is computed is a pure function of the entry and the settings (the initial and critical
crack where the entry leaves them null, the material's row), so it is recomputed where needed
(cached) rather than stored, and a changed materials file takes effect at the next start like
every setting.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

from app.config import Settings
from model.crack_cases import CrackCase, CrackCaseError, case_from_dict
from model.crack_cases.residual_strength import (
    CriticalCrack,
    ResidualStrength,
    Toughness,
    critical_crack,
    residual_strength,
    toughness_for,
)
from model.crack_cases.tabulate import BetaCurve, beta_curve
from model.materials import material
from model.records import RecordError


@dataclass(frozen=True)
class CrackCaseAnswer:
    """The case, its tabulated beta over [a0, a_crit] (critical_crack_m: typed, the settings',
    or computed), and, where the entry gives a limit stress, the critical crack with the
    toughness it used and the residual strength along the table (MPa, one per point) and at
    a0."""

    case: CrackCase
    critical_crack_m: float
    curve: BetaCurve
    critical: CriticalCrack | None
    toughness: Toughness | None
    limit_stress_mpa: float | None
    residual_strength_mpa: tuple[float, ...] | None
    residual_at_initial: ResidualStrength | None


def crack_case_answer(entry: Any, settings: Settings) -> CrackCaseAnswer | None:
    """The answer for a catalogue entry (StoredLocation, or PUT's values as an object), None
    without a crack case.  Raises RecordError naming the field ('crack_case.<dimension>',
    'limit_stress_mpa', 'initial_crack_m', ...) where the case cannot be used."""
    data = getattr(entry, "crack_case", None)
    if data is None:
        return None
    try:
        case = case_from_dict(data)
    except CrackCaseError as exc:
        field = "crack_case" if exc.field is None else f"crack_case.{exc.field}"
        raise RecordError("body", None, field, str(exc)) from exc
    base = settings.law()
    initial = getattr(entry, "initial_crack_m", None) or base.initial_crack_m
    limit = getattr(entry, "limit_stress_mpa", None)
    toughness = None
    if limit is not None:
        toughness = _toughness(entry, case, settings)
    typed = getattr(entry, "critical_crack_m", None)
    critical = None if limit is not None else (typed or base.critical_crack_m)
    try:
        return _answer(case, initial, critical, limit, toughness)
    except ValueError as exc:
        field = "limit_stress_mpa" if "max_stress_mpa" in str(exc) else "initial_crack_m"
        message = str(exc).replace("max_stress_mpa", "limit_stress_mpa")
        raise RecordError("body", None, field, message) from exc


def _toughness(entry: Any, case: CrackCase, settings: Settings) -> Toughness:
    """toughness_of, which a limit stress needs: raises RecordError naming
    fracture_toughness_mpa_sqrt_m where there is none."""
    toughness = toughness_of(entry, case, settings)
    if toughness is None:
        raise RecordError(
            "body",
            None,
            "fracture_toughness_mpa_sqrt_m",
            "a limit stress needs a toughness: give fracture_toughness_mpa_sqrt_m or a material",
        )
    return toughness


def toughness_of(entry: Any, case: CrackCase, settings: Settings) -> Toughness | None:
    """The entry's own K and yield strength where given, else its material's (the entry's,
    else the settings'); K_c or K_IC by the case's thickness (toughness_for); None where
    neither the entry nor a material gives a toughness."""
    name = getattr(entry, "material", None) or settings.material
    row = material(name, settings.materials_file) if name is not None else None
    given = getattr(entry, "fracture_toughness_mpa_sqrt_m", None)
    yield_strength = getattr(entry, "yield_strength_mpa", None)
    if yield_strength is None and row is not None:
        yield_strength = row.yield_strength_mpa
    if given is not None:
        return Toughness(given, "given", yield_strength)
    if row is None:
        return None
    thickness = getattr(case, "thickness_m", None)
    return toughness_for(row.k_ic_mpa_sqrt_m, row.k_c_mpa_sqrt_m, yield_strength, thickness)


@lru_cache(maxsize=256)
def _answer(
    case: CrackCase,
    initial_crack_m: float,
    typed_critical_m: float | None,
    limit_stress_mpa: float | None,
    toughness: Toughness | None,
) -> CrackCaseAnswer:
    critical = None
    end = typed_critical_m
    if limit_stress_mpa is not None:
        assert toughness is not None
        critical = critical_crack(case, limit_stress_mpa, toughness, initial_crack_m)
        end = critical.crack_length_m
    assert end is not None
    curve = beta_curve(case, initial_crack_m, end)
    strengths = None
    at_initial = None
    if toughness is not None:
        strengths = tuple(
            residual_strength(case, a, toughness).stress_mpa for a in curve.table.crack_length_m
        )
        at_initial = residual_strength(case, initial_crack_m, toughness)
    return CrackCaseAnswer(
        case, end, curve, critical, toughness, limit_stress_mpa, strengths, at_initial
    )
