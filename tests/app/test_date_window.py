"""app.date_window: the as-of window as a pattern, exact to the day, read alike by Python's re
and by the Rust engine pydantic validates with (schemathesis draws from the pattern as Python
reads it; a server-side validator or a client may read it as ECMA or Rust does)."""

from __future__ import annotations

import random
import re
from datetime import date, timedelta
from typing import Annotated

import pytest
from pydantic import Field as PydanticField
from pydantic import TypeAdapter, ValidationError

from app.date_window import date_window_pattern

_FIRST, _LAST = date(1900, 1, 1), date(2100, 12, 31)
DAYS = [_FIRST + timedelta(days=n) for n in range((_LAST - _FIRST).days + 1)]


def _windows() -> list[tuple[date, date]]:
    drawn = random.Random(42)
    chosen = [
        (date(1950, 1, 1), date(2033, 12, 29)),  # the tests' window
        (date(2000, 1, 1), date(2000, 1, 1)),  # one day
        (date(1999, 12, 31), date(2000, 1, 1)),  # across a century
        (date(2019, 2, 28), date(2019, 3, 1)),
    ]
    return chosen + [tuple(sorted(drawn.sample(DAYS, 2))) for _ in range(12)]  # type: ignore[misc]


@pytest.mark.parametrize(("first", "last"), _windows())
def test_the_pattern_matches_the_window_and_nothing_else(first: date, last: date) -> None:
    pattern = re.compile(date_window_pattern(first, last))
    wrong = [d for d in DAYS if bool(pattern.fullmatch(d.isoformat())) != (first <= d <= last)]
    assert wrong == []


def test_the_rust_engine_reads_it_as_python_does() -> None:
    first, last = date(1950, 1, 1), date(2033, 12, 29)
    text = date_window_pattern(first, last)
    rust = TypeAdapter(Annotated[str, PydanticField(pattern=text)])
    for day in (
        first,
        last,
        first - timedelta(days=1),
        last + timedelta(days=1),
        date(2000, 2, 29),
    ):
        try:
            rust.validate_python(day.isoformat())
            taken = True
        except ValidationError:
            taken = False
        assert taken == (first <= day <= last), day
    with pytest.raises(ValidationError):
        rust.validate_python("2000-01-01\n")  # no trailing newline either


def test_a_window_that_ends_before_it_starts_is_refused() -> None:
    with pytest.raises(ValueError, match="precedes"):
        date_window_pattern(date(2000, 1, 2), date(2000, 1, 1))
