"""The error of a bad record file or frame (model.records, model.record_bounds)."""

from __future__ import annotations


class RecordError(ValueError):
    """A bad record file or frame, located for the person who has to fix it.

    source: file name (or a label such as "flights"); row: 1-based data row, header excluded
    (None when the problem is not one row's, e.g. a missing column); column: the column name or
    None; reason: what is wrong, with the offending value.  str() reads e.g.
    "flights.csv row 12, column stress_range_mpa: must be > 0, got -3".
    """

    def __init__(self, source: str, row: int | None, column: str | None, reason: str) -> None:
        self.source, self.row, self.column, self.reason = source, row, column, reason
        message = source if row is None else f"{source} row {row}"
        if column is not None:
            message += f", column {column}"
        super().__init__(f"{message}: {reason}")

    def __reduce__(self) -> tuple[type[RecordError], tuple[str, int | None, str | None, str]]:
        # keeps the error intact across processes (the default would call __init__(message))
        return (RecordError, (self.source, self.row, self.column, self.reason))
