"""The client's tables as a person reads them in a pipe or a file."""

from __future__ import annotations

import pytest

from app.cli import output as out


def test_a_facts_table_keeps_its_title_on_one_line_and_has_no_empty_heading(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """`client inspect --file` printed 'inspections of 4' over 'tail(s)' and a row of blank
    headings above its three counts."""
    items = [("inserted", "inserted", 16, "16"), ("flagged", "flagged", 0, "0")]
    out.facts("table", {}, items, title="inspections of 4 tail(s)")
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].strip() == "inspections of 4 tail(s)"
    body = [line for line in lines[1:] if any(ch.isalnum() for ch in line)]
    assert [line.split()[1] for line in body] == ["inserted", "flagged"]


def test_a_table_with_headings_still_shows_them(capsys: pytest.CaptureFixture[str]) -> None:
    columns = [out.Column("tail", "tail"), out.Column("n", "flights", numeric=True)]
    out.emit("table", {}, [{"tail": "EI-FA", "n": 3}], columns, title="t")
    printed = capsys.readouterr().out
    assert "tail" in printed and "flights" in printed and "EI-FA" in printed
