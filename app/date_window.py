"""A window of ISO dates as a regular expression, for a JSON Schema that must state it.

JSON Schema's `format: date` has no minimum or maximum, so an as-of date's window
(app.budget.as_of_window) could not be stated and a schema-valid date outside it was refused
(422).  ISO dates of four-digit years sort as their text does, so the window is a range of
fixed-width strings, which a pattern of digit classes states exactly; `format: date` still
says which days exist.  The pattern uses only literals, digit classes and groups, which ECMA,
Python and Rust regular expressions read alike.
"""

from __future__ import annotations

from datetime import date

_SHAPE = "dddd-dd-dd"  # d: a digit; anything else: itself


def date_window_pattern(first: date, last: date) -> str:
    """An anchored pattern matched by the text YYYY-MM-DD of every date from `first` to `last`
    (inclusive) and by no other such text of a real date.  Raises ValueError where last
    precedes first."""
    if last < first:
        raise ValueError(f"last ({last}) precedes first ({first})")
    return f"^({_between(first.isoformat(), last.isoformat(), _SHAPE)})$"


def _between(low: str, high: str, shape: str) -> str:
    """Strings of `shape` from low to high (same shape, low <= high), as alternatives (the
    digits and "-" outside a class mean themselves in every dialect)."""
    if not shape:
        return ""
    if low[0] == high[0]:
        return low[0] + _group(_between(low[1:], high[1:], shape[1:]))
    lo, hi = int(low[0]), int(high[0])
    parts = [low[0] + _group(_at_least(low[1:], shape[1:]))]
    if hi - lo > 1:
        parts.append(_digits(lo + 1, hi - 1) + _any(shape[1:]))
    parts.append(high[0] + _group(_at_most(high[1:], shape[1:])))
    return "|".join(parts)


def _at_least(low: str, shape: str) -> str:
    """Strings of `shape` from low up."""
    if not shape:
        return ""
    if shape[0] != "d":
        return shape[0] + _group(_at_least(low[1:], shape[1:]))
    parts = [low[0] + _group(_at_least(low[1:], shape[1:]))]
    if low[0] != "9":
        parts.append(_digits(int(low[0]) + 1, 9) + _any(shape[1:]))
    return "|".join(parts)


def _at_most(high: str, shape: str) -> str:
    """Strings of `shape` up to high."""
    if not shape:
        return ""
    if shape[0] != "d":
        return shape[0] + _group(_at_most(high[1:], shape[1:]))
    parts = [high[0] + _group(_at_most(high[1:], shape[1:]))]
    if high[0] != "0":
        parts.append(_digits(0, int(high[0]) - 1) + _any(shape[1:]))
    return "|".join(parts)


def _any(shape: str) -> str:
    return "".join("[0-9]" if c == "d" else c for c in shape)


def _digits(low: int, high: int) -> str:
    return str(low) if low == high else f"[{low}-{high}]"


def _group(alternatives: str) -> str:
    return f"({alternatives})" if "|" in alternatives else alternatives
