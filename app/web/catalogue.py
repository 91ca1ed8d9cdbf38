"""The catalogue page's rows: each location's geometry factor, its critical crack and why, and
the curves its chart draws (beta(a) and, with a toughness, the residual strength).

Everything is read from the entry and the settings through the services that answer GET
/locations (app.services.records.location_cracks) and the forecast's residual strength
(app.services.forecasts.residual_now), so the page shows what the API says.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.config import Settings
from app.services.forecasts.residual_now import section_of
from app.services.records import location_cracks
from app.services.records.locations import StoredLocation
from model.crack_cases.residual_strength import residual_strength
from model.records import RecordError

# points of the residual-strength curve (log-spaced from a0), drawn a little past a_crit so
# that its crossing of the limit stress is seen
_CURVE_POINTS = 160
_PAST_CRITICAL = 1.25

_CRITERIA = {
    "fracture": "fracture: K = beta S sqrt(pi a) reaches the toughness",
    "net_section_yield": "net-section yield: S A_gross / A_net reaches the yield strength",
    "extent": "the crack reaches the end of its case before either criterion",
}


@dataclass(frozen=True)
class Curves:
    """What a location's chart draws (m, MPa): beta at the tabulated cracks, and the residual
    strength along a finer grid (None: no toughness) with what sets it at each point (its
    criterion: the curve's kink where net-section yield gives way to fracture is explained),
    the limit stress and a_crit."""

    beta_crack_m: tuple[float, ...]
    beta: tuple[float, ...]
    strength_crack_m: tuple[float, ...] | None
    strength_mpa: tuple[float, ...] | None
    limit_stress_mpa: float | None
    critical_crack_m: float
    strength_criterion: tuple[str, ...] | None = None


@dataclass(frozen=True)
class CatalogueRow:
    """One location as the page lists it; curves None where there is no beta(a) to draw (a
    constant factor) or the stored case cannot be computed (error says why)."""

    name: str
    description: str
    geometry: str
    critical_crack_m: float | None
    reason: str
    warning: str | None
    toughness: str | None
    curves: Curves | None
    error: str | None


def catalogue_rows(entries: list[StoredLocation], settings: Settings) -> list[CatalogueRow]:
    """Every entry's row, in the catalogue's order."""
    return [_row(entry, settings) for entry in entries]


def _row(entry: StoredLocation, settings: Settings) -> CatalogueRow:
    geometry = _geometry(entry, settings)
    try:
        answer = location_cracks.crack_case_answer(entry, settings)
    except RecordError as exc:
        return CatalogueRow(
            entry.name, entry.description, geometry, None, "", None, None, None, str(exc)
        )
    base = settings.law()
    initial = entry.initial_crack_m or base.initial_crack_m
    if answer is not None and answer.critical is not None:
        assert answer.toughness is not None
        critical = answer.critical.crack_length_m
        reason = (
            f"computed at {entry.limit_stress_mpa:g} MPa: {_CRITERIA[answer.critical.criterion]}"
        )
        warning = answer.critical.warning or answer.curve.warning
    elif entry.critical_crack_m is not None:
        critical, reason = entry.critical_crack_m, "typed in the catalogue"
        warning = None if answer is None else answer.curve.warning
    else:
        critical, reason = base.critical_crack_m, "the service's default (settings)"
        warning = None if answer is None else answer.curve.warning
    section = section_of(entry)
    toughness = None if section is None else location_cracks.toughness_of(entry, section, settings)
    curves = None
    if section is not None:
        if answer is not None:
            beta_at, beta = answer.curve.table.crack_length_m, answer.curve.table.factor
        else:
            assert entry.geometry_table is not None  # a section without a case is its table
            beta_at = tuple(entry.geometry_table["crack_length_m"])
            beta = tuple(entry.geometry_table["factor"])
        strength_at = strengths = criteria = None
        if toughness is not None:
            end = min(critical * _PAST_CRITICAL, section.extent_m() * (1 - 1e-6))
            grid = np.geomspace(initial, end, _CURVE_POINTS)
            strength_at = tuple(float(a) for a in grid)
            along = [residual_strength(section, float(a), toughness) for a in grid]
            strengths = tuple(at.stress_mpa for at in along)
            criteria = tuple(at.criterion for at in along)
        curves = Curves(
            tuple(float(a) for a in beta_at),
            tuple(float(b) for b in beta),
            strength_at,
            strengths,
            entry.limit_stress_mpa,
            critical,
            criteria,
        )
    said = None
    if toughness is not None:
        said = f"{toughness.fracture_toughness_mpa_sqrt_m:g} MPa√m ({toughness.kind})"
        if toughness.yield_strength_mpa is not None:
            said += f", yield {toughness.yield_strength_mpa:g} MPa"
    return CatalogueRow(
        entry.name, entry.description, geometry, critical, reason, warning, said, curves, None
    )


def _geometry(entry: StoredLocation, settings: Settings) -> str:
    """The geometry factor in words: the case and its dimensions, a table, or a constant."""
    if entry.crack_case is not None:
        case = dict(entry.crack_case)
        name = case.pop("type")
        dimensions = ", ".join(f"{k} {v}" for k, v in case.items() if v is not None)
        return f"{name} ({dimensions})" if dimensions else str(name)
    if entry.geometry_table is not None:
        return f"table of {len(entry.geometry_table['crack_length_m'])} points"
    factor = entry.geometry_factor or settings.law().geometry_factor
    return f"constant F = {factor:g}"
