"""The catalogue page's rows: each location's geometry factor, its critical crack and why, the
residual strength at its initial crack and what sets it, and the curves its chart draws (beta(a)
with the case's validity limit and, with a toughness, the residual strength).

Everything is read from the entry and the settings through the services that answer GET
/locations (app.services.records.location_cracks) and the forecast's residual strength
(app.services.forecasts.residual_now), so the page shows what the API says.  Every crack
length and dimension on the page is in mm (app.web.format.mm), as on the fleet's other pages;
the page words its own texts from the same numbers, short enough for a table's cell, each
number kept on one line with its unit (unbroken).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from app.config import Settings
from app.services.forecasts.residual_now import section_of
from app.services.records import location_cracks
from app.services.records.locations import StoredLocation
from app.web import format as fmt
from model.crack_cases import CrackCase
from model.crack_cases.base import UNBOUNDED_M
from model.crack_cases.residual_strength import ResidualStrength, Toughness, residual_strength
from model.records import RecordError

# points of the residual-strength curve (log-spaced from a0), drawn a little past a_crit so
# that its crossing of the limit stress is seen
_CURVE_POINTS = 160
PAST_CRITICAL = 1.25
# the catalogue's names of non-length dimensions where the field's symbol says more
_SYMBOLS = {"aspect_ratio": "a/c", "growth_exponent": "m"}
# the spaces a line may not break at: before a number or "=", and between a number and its
# unit, so that no number is read apart from its name or unit in a narrow cell
_GLUED = re.compile(r" (?=[+\u2212-]?\d|=|(?:mm|MPa)\b|%)")


@dataclass(frozen=True)
class Curves:
    """What a location's chart draws (m, MPa): beta at the tabulated cracks, and the residual
    strength along a finer grid (None: no toughness) with what sets it at each point (its
    criterion: the curve's kink where net-section yield gives way to fracture is explained),
    the limit stress, a_crit, and the case's validity limit with its reason (the limit None:
    the case has none on a, an infinite plate; the chart draws the limit where it lies on its
    crack axis and says where it lies beyond)."""

    beta_crack_m: tuple[float, ...]
    beta: tuple[float, ...]
    strength_crack_m: tuple[float, ...] | None
    strength_mpa: tuple[float, ...] | None
    limit_stress_mpa: float | None
    critical_crack_m: float
    strength_criterion: tuple[str, ...] | None = None
    validity_limit_m: float | None = None
    validity_reason: str | None = None


@dataclass(frozen=True)
class StrengthWords:
    """The residual strength at a0 in a cell's three lines: the value at a0, what sets it, and
    its margin on the limit stress (None: no limit stress)."""

    value: str
    governs: str
    margin: str | None


@dataclass(frozen=True)
class CatalogueRow:
    """One location as the page lists it: its geometry (a case's name, a table, a constant)
    with the case's dimensions (lengths in mm, the unit in the column's header); curves None
    where there is no beta(a) to draw (a constant factor) or the stored case cannot be computed
    (error says why).  warning: where a_crit lies beyond the case's validity limit; toughness
    and strength_at_initial: the residual strength at a0 and what it is computed from (None:
    no toughness)."""

    name: str
    description: str
    geometry: str
    dimensions: tuple[str, ...]
    critical_crack_m: float | None
    reason: str
    warning: str | None
    toughness: str | None
    curves: Curves | None
    error: str | None
    strength_at_initial: StrengthWords | None = None


def catalogue_rows(entries: list[StoredLocation], settings: Settings) -> list[CatalogueRow]:
    """Every entry's row, in the catalogue's order."""
    return [_row(entry, settings) for entry in entries]


def _row(entry: StoredLocation, settings: Settings) -> CatalogueRow:
    named, sized = _geometry(entry, settings)
    geometry, dimensions = _unbroken(named), tuple(map(_unbroken, sized))
    try:
        answer = location_cracks.crack_case_answer(entry, settings)
    except RecordError as exc:
        return CatalogueRow(
            entry.name,
            entry.description,
            geometry,
            dimensions,
            critical_crack_m=None,
            reason="",
            warning=None,
            toughness=None,
            curves=None,
            error=str(exc),
        )
    base = settings.law()
    initial = entry.initial_crack_m or base.initial_crack_m
    section = section_of(entry)
    toughness = None if section is None else location_cracks.toughness_of(entry, section, settings)
    by_fracture = (
        answer is not None
        and answer.critical is not None
        and answer.critical.criterion == "fracture"
    )
    if answer is not None and answer.critical is not None:
        assert answer.toughness is not None and section is not None
        critical = answer.critical.crack_length_m
        reason = (
            f"computed at the limit stress {entry.limit_stress_mpa:g} MPa: "
            + _criterion_sentence(answer.critical.criterion, answer.toughness, section)
        )
    elif entry.critical_crack_m is not None:
        critical, reason = entry.critical_crack_m, "typed in the catalogue (critical_crack_m)"
    else:
        critical, reason = base.critical_crack_m, "the service's default (settings)"
    warning = None
    if section is not None and answer is not None:
        warning = _beyond_validity(section, critical, by_fracture=by_fracture)
    curves = None
    if section is not None:
        curves = _curves(entry, answer, section, toughness, initial, critical)
    said = strength = None
    if toughness is not None and section is not None:
        said = toughness_name(toughness)
        if toughness.yield_strength_mpa is not None:
            said += f", yield strength {toughness.yield_strength_mpa:g} MPa"
        at_initial = residual_strength(section, initial, toughness)
        strength = _strength_words(at_initial, initial, toughness, entry.limit_stress_mpa)
    return CatalogueRow(
        entry.name,
        entry.description,
        geometry,
        dimensions,
        critical,
        _unbroken(reason),
        None if warning is None else _unbroken(warning),
        None if said is None else _unbroken(said),
        curves,
        None,
        strength,
    )


def _curves(
    entry: StoredLocation,
    answer: location_cracks.CrackCaseAnswer | None,
    section: CrackCase,
    toughness: Toughness | None,
    initial: float,
    critical: float,
) -> Curves:
    if answer is not None:
        beta_at, beta = answer.curve.table.crack_length_m, answer.curve.table.factor
    else:
        assert entry.geometry_table is not None  # a section without a case is its table
        beta_at = tuple(entry.geometry_table["crack_length_m"])
        beta = tuple(entry.geometry_table["factor"])
    strength_at = strengths = criteria = None
    if toughness is not None:
        end = min(critical * PAST_CRITICAL, section.extent_m() * (1 - 1e-6))
        grid = np.geomspace(initial, end, _CURVE_POINTS)
        strength_at = tuple(float(a) for a in grid)
        along = [residual_strength(section, float(a), toughness) for a in grid]
        strengths = tuple(at.stress_mpa for at in along)
        criteria = tuple(at.criterion for at in along)
    validity = section.validity()
    bounded = validity.crack_length_m < UNBOUNDED_M
    return Curves(
        tuple(float(a) for a in beta_at),
        tuple(float(b) for b in beta),
        strength_at,
        strengths,
        entry.limit_stress_mpa,
        critical,
        criteria,
        validity.crack_length_m if bounded else None,
        validity.reason,
    )


def toughness_name(toughness: Toughness) -> str:
    """The toughness by what it is: 'K_c 80 MPa√m', 'K_IC 34 MPa√m', or the location's own."""
    if toughness.kind == "given":
        return f"the location's toughness {_short(toughness)} (fracture_toughness_mpa_sqrt_m)"
    return _short(toughness)


def _short(toughness: Toughness) -> str:
    """The toughness where its row has named it in full already: 'K_c 80 MPa√m', '80 MPa√m'."""
    value = f"{toughness.fracture_toughness_mpa_sqrt_m:g} MPa√m"
    return value if toughness.kind == "given" else f"{toughness.kind} {value}"


def _criterion_sentence(criterion: str, toughness: Toughness, section: CrackCase) -> str:
    """What set a_crit, with the value it reached."""
    if criterion == "fracture":
        return f"fracture: K = beta S sqrt(pi a) reaches {_short(toughness)}"
    if criterion == "net_section_yield":
        return (
            "net-section yield: S A_gross / A_net reaches the yield strength "
            f"{toughness.yield_strength_mpa:g} MPa"
        )
    return (
        "neither fracture nor net-section yield is reached before the section ends at "
        f"a = {fmt.mm(section.extent_m())} mm; {section.extent_reason()}"
    )


def _strength_words(
    at: ResidualStrength, initial_m: float, toughness: Toughness, limit_stress_mpa: float | None
) -> StrengthWords:
    """The residual strength at a0, the criterion that sets it, and its margin on the limit."""
    if at.criterion == "fracture":
        governs = f"fracture at {_short(toughness)}"
    elif at.criterion == "net_section_yield":
        governs = f"net-section yield at {toughness.yield_strength_mpa:g} MPa"
    else:
        governs = fmt.criterion_words(at.criterion)
    margin = None
    if limit_stress_mpa is not None:
        margin = (
            f"margin {fmt.signed_percent(at.margin_over(limit_stress_mpa))} on the limit "
            f"stress {limit_stress_mpa:g} MPa"
        )
    return StrengthWords(
        _unbroken(f"{fmt.number(at.stress_mpa, 0)} MPa at a0 = {fmt.mm(initial_m)} mm"),
        _unbroken(f"set by {governs}"),
        None if margin is None else _unbroken(margin),
    )


def _unbroken(text: str) -> str:
    """The text with no-break spaces where a line would part a number from its name, its "="
    or its unit ('a = 7.84 mm' stays on one line; the words around it still wrap)."""
    return _GLUED.sub("\u00a0", text)


def _beyond_validity(section: CrackCase, critical_m: float, *, by_fracture: bool) -> str | None:
    """Said where a_crit lies past the case's validity limit (None inside it): what the
    numbers then rest on (by_fracture: a_crit found where K reaches the toughness, which reads
    beta past the limit)."""
    validity = section.validity()
    if critical_m <= validity.crack_length_m:
        return None
    said = (
        f"a_crit lies beyond the validity limit a = {fmt.mm(validity.crack_length_m)} mm, "
        f"{validity.reason}: "
    )
    if by_fracture:
        said += "it is computed on the closed form extrapolated past the limit, and "
    return said + "the march holds beta at its value at the limit up to a_crit"


def _geometry(entry: StoredLocation, settings: Settings) -> tuple[str, tuple[str, ...]]:
    """The geometry factor in words: the case and its dimensions (lengths in mm, said by the
    column's header), a table and its range, or a constant."""
    if entry.crack_case is not None:
        case = dict(entry.crack_case)
        name = case.pop("type")
        return str(name), tuple(_dimension(k, v) for k, v in case.items() if v is not None)
    if entry.geometry_table is not None:
        at = entry.geometry_table["crack_length_m"]
        return f"table of {len(at)} points", (f"a {fmt.mm(at[0])}–{fmt.mm(at[-1])}",)
    factor = entry.geometry_factor or settings.law().geometry_factor
    return f"constant F = {factor:g}", ()


def _dimension(key: str, value: object) -> str:
    """One dimension of a case as the page says it: lengths (fields ending _m) in mm, the
    unit said by the column's header."""
    if key.endswith("_m"):
        stem = key[:-2].replace("_", " ")
        if isinstance(value, list | tuple):
            return f"{stem} {fmt.mm(value[0])}–{fmt.mm(value[-1])} ({len(value)} points)"
        assert isinstance(value, int | float)
        return f"{stem} {fmt.mm(value)}"
    if isinstance(value, list | tuple):
        return f"{key.replace('_', ' ')} {min(value):g}–{max(value):g}"
    return f"{_SYMBOLS.get(key, key.replace('_', ' '))} {value}"
