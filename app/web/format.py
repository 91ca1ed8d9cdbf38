"""Numbers and dates as structures engineers read them: mm with 2 decimals, percent, ISO dates.

Used as Jinja filters by the templates and by the charts' labels; every function takes None
(a value the service could not give: not finite, not within the horizon) and shows a dash.
"""

from __future__ import annotations

from datetime import datetime

DASH = "—"


def mm(metres: float | None) -> str:
    """A crack length in m shown in mm with 2 decimals: 0.012345 -> '12.35'."""
    if metres is None:
        return DASH
    return f"{metres * 1000:.2f}"


def crack_mm(metres: float | None, critical_m: float) -> str:
    """A projected crack in mm; at or past a_crit (or diverged: None) the model has no meaning
    there, so it reads '> a_crit'."""
    if metres is None or metres >= critical_m:
        return "> a_crit"
    return mm(metres)


def crack_band(low: float | None, high: float | None, critical_m: float) -> str:
    """A projected p05-p95 crack band in mm, '' when even its p05 is past a_crit."""
    if low is None or low >= critical_m:
        return ""
    return f"{mm(low)}–{crack_mm(high, critical_m)}"


def percent(probability: float | None) -> str:
    """A probability in percent with one decimal; the ends kept exact: 0 %, <0.1 %, 100 %."""
    if probability is None:
        return DASH
    if probability <= 0:
        return "0 %"
    if probability >= 1:
        return "100 %"
    if probability < 0.001:
        return "<0.1 %"
    if probability > 0.999:
        return ">99.9 %"
    return f"{probability * 100:.1f} %"


def date(value: datetime | None) -> str:
    """An ISO 8601 date (UTC): '2026-03-14'."""
    if value is None:
        return DASH
    return value.date().isoformat()


def timestamp(value: datetime | None) -> str:
    """An ISO 8601 date and minute (UTC): '2026-03-14 09:30Z'."""
    if value is None:
        return DASH
    return value.strftime("%Y-%m-%d %H:%MZ")


def number(value: float | None, digits: int = 1) -> str:
    if value is None:
        return DASH
    return f"{value:,.{digits}f}"


def count(value: int | None) -> str:
    """An integer with thousands separators: 7,300."""
    if value is None:
        return DASH
    return f"{value:,d}"


def signed_percent(value: float | None) -> str:
    """A margin over a limit, signed, in percent with one decimal: 0.993 -> '+99.3 %'."""
    if value is None:
        return DASH
    return f"{value * 100:+.1f} %".replace("-", "\u2212")


_CRITERIA = {
    "fracture": "fracture",
    "net_section_yield": "net-section yield",
    "extent": "section severed",
}


def criterion_words(name: str) -> str:
    """What sets a residual strength, in words: 'net_section_yield' -> 'net-section yield'."""
    return _CRITERIA.get(name, name)


def strength_words(
    residual_strength_mpa: float, criterion: str, margin: float, limit_stress_mpa: float
) -> str:
    """A residual strength, what sets it and its margin over the limit stress, in one line
    (a tail's page and the client alike): '299 MPa (net-section yield), margin +99.3 % on the
    limit 150 MPa'.  The arguments are a line's residual_strength as the API names them
    (app.schemas_residual.LineStrengthOut)."""
    return (
        f"{number(residual_strength_mpa, 0)} MPa ({criterion_words(criterion)}), "
        f"margin {signed_percent(margin)} on the limit {number(limit_stress_mpa, 0)} MPa"
    )


def strength_margin(residual_strength_mpa: float | None, margin: float | None) -> str:
    """A residual strength and its margin, short, for a table's cell (the fleet page's and the
    client's ranking): '299 MPa, +99.3 %'; a dash without one."""
    if residual_strength_mpa is None or margin is None:
        return DASH
    return f"{number(residual_strength_mpa, 0)} MPa, {signed_percent(margin)}"


def strength(line: object) -> str:
    """strength_words of an object with those four attributes (a LineStrength)."""
    names = ("residual_strength_mpa", "criterion", "margin", "limit_stress_mpa")
    return strength_words(**{name: getattr(line, name) for name in names})


_NAMES = ("inspection", "tail", "inspection_id")


def culprit(entry: object) -> str:
    """One inspection the promotion gate blames for a refusal, in one line: its name
    ("tail/inspection_id", app.services.jobs.promotion) first, then its other facts
    ('T3/I-2025-01: candidate_error_pct 152.3').  Anything but a mapping is shown as it is."""
    if not isinstance(entry, dict):
        return str(entry)
    named = " ".join(str(entry[k]) for k in _NAMES if entry.get(k) is not None)
    facts = ", ".join(f"{key} {_fact(value)}" for key, value in entry.items() if key not in _NAMES)
    return f"{named}: {facts}" if named and facts else named or facts


def _fact(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


FILTERS = {
    "culprit": culprit,
    "mm": mm,
    "crack_mm": crack_mm,
    "crack_band": crack_band,
    "percent": percent,
    "date": date,
    "timestamp": timestamp,
    "number": number,
    "count": count,
    "signed_percent": signed_percent,
    "criterion": criterion_words,
    "strength": strength,
}
