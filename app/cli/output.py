"""What the client prints: a table for people (rich), or CSV / JSON for tools.

Every command hands over rows (dicts, one key per column) and the columns to show; --json
prints the server's answer itself, --csv the rows with the API's values (SI units, ISO 8601
UTC times with Z), the table the same rows as engineers read them (mm, percent, dates).
"""

from __future__ import annotations

import csv
import json
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Any, Literal

from rich.console import Console
from rich.table import Table

from app.web import format as fmt

Mode = Literal["table", "csv", "json"]
_PIPE_WIDTH = 200


@dataclass(frozen=True)
class Column:
    """A column: its key in the rows, its heading and how a person reads its value."""

    key: str
    heading: str
    show: Callable[[Any], str] = str
    numeric: bool = False


def mode_of(args: Any) -> Mode:
    """The output mode an argparse namespace with --json and --csv asks for."""
    return "json" if args.json else "csv" if args.csv else "table"


def _time(value: str | None) -> datetime | None:
    return None if value is None else datetime.fromisoformat(value.replace("Z", "+00:00"))


def mm(value: float | None) -> str:
    return fmt.mm(value)


def percent(value: float | None) -> str:
    return fmt.percent(value)


def day(value: str | None) -> str:
    """An API timestamp shown as its ISO date (UTC)."""
    return fmt.date(_time(value))


def stamp(value: str | None) -> str:
    """An API timestamp shown to the minute (UTC)."""
    return fmt.timestamp(_time(value))


def text(value: Any) -> str:
    return fmt.DASH if value is None else str(value)


def yes(value: bool | None) -> str:
    return "" if not value else "yes"


def emit(
    mode: Mode,
    answer: Any,
    rows: Sequence[dict[str, Any]],
    columns: Sequence[Column],
    *,
    title: str | None = None,
) -> None:
    """Print the answer: the server's JSON, the rows as CSV, or the rows as a table."""
    if mode == "json":
        print(json.dumps(answer, indent=2))
    elif mode == "csv":
        writer = csv.DictWriter(
            sys.stdout,
            fieldnames=[c.key for c in columns],
            extrasaction="ignore",
            lineterminator="\n",
        )
        writer.writeheader()
        for row in rows:
            writer.writerow({c.key: "" if row.get(c.key) is None else row[c.key] for c in columns})
    else:
        # the table at least as wide as its title (rich wraps a title to the table's width:
        # "inspections of 4" over "tail(s)"); a two-column table of facts has no headings
        table = Table(
            title=title,
            title_justify="left",
            header_style="bold",
            min_width=len(title) if title else None,
            show_header=any(column.heading for column in columns),
        )
        for column in columns:
            table.add_column(
                column.heading, justify="right" if column.numeric else "left", overflow="fold"
            )
        for row in rows:
            table.add_row(*(column.show(row.get(column.key)) for column in columns))
        # A pipe or a file gets the whole table; a terminal its own width.
        width = None if sys.stdout.isatty() else _PIPE_WIDTH
        Console(soft_wrap=False, width=width).print(table)


def facts(
    mode: Mode, answer: Any, items: Sequence[tuple[str, str, Any, str]], *, title: str
) -> None:
    """One object as a two-column table (what, shown value), or as (key, raw value) CSV rows.
    items: (key, heading, raw value, value as shown)."""
    if mode == "table":
        rows = [{"what": heading, "value": shown} for _, heading, _, shown in items]
        emit(mode, answer, rows, [Column("what", ""), Column("value", "")], title=title)
        return
    rows = [{"key": key, "value": raw} for key, _, raw, _ in items]
    emit(mode, answer, rows, [Column("key", "key"), Column("value", "value")])
