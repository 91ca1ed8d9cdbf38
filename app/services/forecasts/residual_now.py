"""The residual strength of a tail's section at its crack now, and its margin over the limit
stress (issue 41's deliverable 3), as a forecast reports it.

The crack now is the forecast's sampled crack on the as-of date: its p50, and its p95, the
conservative crack, whose residual strength is the conservative one (the strength falls as the
crack grows).  The section is the location's crack case, else its geometry table read as a
user's table (an infinite body: fracture only); its toughness and yield strength are the
catalogue's (app.services.records.location_cracks.toughness_of).  It is reported only where the
location gives a limit stress to hold it against (issue 41: a location of today's catalogue
answers as before, though FLEETPINN_MATERIAL gives it a toughness); a location with a constant
factor, or without a toughness, cannot compute it: None either.  A crack at or past the case's extent (the
section severed), or not finite (the march ran away past a_crit), carries nothing: 0 MPa,
criterion "extent".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from app.config import Settings
from app.services.records.location_cracks import toughness_of
from app.services.records.locations import StoredLocation
from model.crack_cases import CrackCase, CrackCaseError, case_from_dict
from model.crack_cases.residual_strength import (
    Criterion,
    ResidualStrength,
    Toughness,
    residual_strength,
)
from model.crack_cases.table import UserTable


@dataclass(frozen=True)
class StrengthAt:
    """The residual strength (MPa) at one crack (m; None: not finite), the criterion that sets
    it, and its margin over the limit stress (strength / limit - 1)."""

    crack_length_m: float | None
    residual_strength_mpa: float
    criterion: Criterion
    margin: float


@dataclass(frozen=True)
class ResidualNow:
    """The residual strength at the crack now, p50 and p95 (the conservative value), under the
    toughness it was computed with and the location's limit stress."""

    p50: StrengthAt
    p95: StrengthAt
    limit_stress_mpa: float
    toughness_mpa_sqrt_m: float
    toughness_kind: str
    yield_strength_mpa: float | None


@dataclass(frozen=True)
class LineStrength:
    """The residual strength (MPa) at an aircraft's line's p50 crack, the criterion that sets
    it and its margin over the location's limit stress, the margin being what a decision reads
    (an aircraft's line, a ranking's row, an export's columns)."""

    residual_strength_mpa: float
    criterion: Criterion
    margin: float
    limit_stress_mpa: float

    @classmethod
    def of(cls, now: ResidualNow | None) -> LineStrength | None:
        """The p50 of a forecast's residual strength; None without one."""
        if now is None:
            return None
        at = now.p50
        return cls(at.residual_strength_mpa, at.criterion, at.margin, now.limit_stress_mpa)


def line_strength(
    location: StoredLocation, crack_p50_m: float | None, settings: Settings
) -> LineStrength | None:
    """LineStrength at the p50 crack (m; None: not finite) of a line read from its row; None
    where the location gives no limit stress (or cannot compute a strength)."""
    return LineStrength.of(residual_now(location, crack_p50_m, crack_p50_m, settings))


def section_of(location: StoredLocation) -> CrackCase | None:
    """The location's crack case, else its geometry table as a user's table; None where it has
    neither (a constant factor has no crack case to compute a section from) or its stored case
    can no longer be built."""
    if location.crack_case is not None:
        try:
            return case_from_dict(location.crack_case)
        except CrackCaseError:
            return None
    if location.geometry_table is not None:
        table = location.geometry_table
        return UserTable(tuple(table["crack_length_m"]), tuple(table["factor"]))
    return None


def residual_now(
    location: StoredLocation,
    crack_p50_m: float | None,
    crack_p95_m: float | None,
    settings: Settings,
) -> ResidualNow | None:
    """The residual strength at the p50 and p95 crack now (m; None: not finite), or None where
    the location gives no limit stress or cannot compute it (module docstring)."""
    limit = location.limit_stress_mpa
    if limit is None:
        return None
    case = section_of(location)
    if case is None:
        return None
    toughness = toughness_of(location, case, settings)
    if toughness is None:
        return None

    def at(crack: float | None) -> StrengthAt:
        strength = _strength(case, crack, toughness)
        return StrengthAt(
            crack, strength.stress_mpa, strength.criterion, strength.margin_over(limit)
        )

    return ResidualNow(
        p50=at(crack_p50_m),
        p95=at(crack_p95_m),
        limit_stress_mpa=limit,
        toughness_mpa_sqrt_m=toughness.fracture_toughness_mpa_sqrt_m,
        toughness_kind=toughness.kind,
        yield_strength_mpa=toughness.yield_strength_mpa,
    )


def _strength(case: CrackCase, crack: float | None, toughness: Toughness) -> ResidualStrength:
    if crack is None or not math.isfinite(crack) or crack >= case.extent_m():
        return ResidualStrength(0.0, "extent")
    return residual_strength(case, crack, toughness)
