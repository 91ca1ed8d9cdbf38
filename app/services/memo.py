"""A bounded per-process memo of values derived from stored state, each kept with the stamp of
the state it was derived from and served only while that stamp is still the stored one.

The caller reads the current stamp (e.g. app.tables.Forecast.stamp, new on every write of a
row) in the request's own transaction and asks for the value kept under it: a write by any
process changes the stamp, so a value derived from an older state is never served.  The memo
only saves the work of deriving the value again; what it keeps is bounded by `size` entries,
least recently used first out.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Hashable
from typing import Generic, TypeVar

Value = TypeVar("Value")


class StampedMemo(Generic[Value]):
    """key -> (stamp, value), at most `size` keys; safe to share between threads."""

    def __init__(self, size: int) -> None:
        if size < 1:
            raise ValueError(f"size must be at least 1, got {size}")
        self.size = size
        self._entries: OrderedDict[Hashable, tuple[object, Value]] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: Hashable, stamp: object) -> Value | None:
        """The value kept for `key` if it was derived from `stamp`, else None."""
        with self._lock:
            entry = self._entries.get(key)
            if entry is None or entry[0] != stamp:
                return None
            self._entries.move_to_end(key)
            return entry[1]

    def last(self, key: Hashable) -> tuple[object, Value] | None:
        """(stamp, value) last kept for `key` whatever its stamp, for a caller that can bring
        it up to date more cheaply than derive it anew; None where nothing is kept."""
        with self._lock:
            return self._entries.get(key)

    def put(self, key: Hashable, stamp: object, value: Value) -> None:
        """Keep `value`, derived from `stamp`, for `key` (replacing what was kept for it)."""
        with self._lock:
            self._entries[key] = (stamp, value)
            self._entries.move_to_end(key)
            while len(self._entries) > self.size:
                self._entries.popitem(last=False)

    def clear(self) -> None:
        with self._lock:
            self._entries.clear()
