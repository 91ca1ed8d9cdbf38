"""Bounded IN (...) lists: ids queried in slices, below every backend's bound-parameter limit.

Kept apart from app.storage (pandas, numpy) so that the key and audit services import nothing
heavy (`fleetpinn keys` starts in well under a second)."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import TypeVar

T = TypeVar("T")

IN_LIST = 500  # values per IN (...) list


def chunks(values: Sequence[T], size: int = IN_LIST) -> Iterator[Sequence[T]]:
    """Consecutive slices of at most `size` values (bounded IN lists)."""
    for start in range(0, len(values), size):
        yield values[start : start + size]
