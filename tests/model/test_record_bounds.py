"""A record file's shape is refused before it is parsed (issue 42): the long row, the
decompression bomb, the file of too many rows; a file within the bounds reads as before."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from model.record_bounds import MAX_LINE_BYTES, check_csv
from model.records import RecordError, read_table

HEADER = "tail,flight_id,flown_at,stress_range_mpa\n"
ROW = "H1,F1,2024-01-01T00:00:00Z,100\n"


def _refusal(path: Path, **bounds: int) -> RecordError:
    started = time.monotonic()
    with pytest.raises(RecordError) as caught:
        read_table(path, **bounds)
    assert time.monotonic() - started < 5.0  # the reader took 31 s on the long row
    return caught.value


@pytest.mark.parametrize("extra", [1, 40_000, 1_000_000])
def test_a_row_with_more_fields_than_the_header_is_named(tmp_path: Path, extra: int) -> None:
    path = tmp_path / "wide.csv"
    path.write_text(HEADER + ROW * 2 + ROW.rstrip() + ",1" * extra + "\n" + ROW)
    error = _refusal(path)
    assert error.row == 3
    # a line read whole counts its fields; one past a megabyte is refused at what was read
    words = f"has {4 + extra} fields" if extra < 1_000_000 else "has at least"
    assert words in error.reason and "more than the header's 4" in error.reason


def test_a_quoted_comma_is_no_field(tmp_path: Path) -> None:
    header = HEADER.rstrip() + ",mission\n"
    path = tmp_path / "quoted.csv"
    path.write_text(header + 'H1,F1,2024-01-01T00:00:00Z,100,"climb, cruise"\n')
    assert read_table(path)["mission"].tolist() == ["climb, cruise"]
    path.write_text(header + 'H1,F1,2024-01-01T00:00:00Z,100,"climb, cruise",x\n')
    assert "has 6 fields, more than the header's 5" in _refusal(path).reason


def test_a_long_line_is_refused_naming_its_row(tmp_path: Path) -> None:
    path = tmp_path / "long.csv"
    path.write_text(HEADER + ROW + "H1,F2,2024-01-01T00:00:00Z," + "1" * MAX_LINE_BYTES + "\n")
    error = _refusal(path)
    assert error.row == 2
    assert f"line of {MAX_LINE_BYTES + 27} bytes, at most {MAX_LINE_BYTES}" in error.reason
    # the last line, without a newline, is checked too
    path.write_text(HEADER + ROW + "H1,F2,2024-01-01T00:00:00Z,100,1")
    assert _refusal(path).row == 2


def test_rows_are_counted_before_the_csv_is_parsed(tmp_path: Path) -> None:
    path = tmp_path / "many.csv"
    path.write_text(HEADER + ROW * 10 + "\n\n")
    assert len(read_table(path, max_rows=10)) == 10  # blank lines are no rows
    error = _refusal(path, max_rows=9)
    assert (
        error.row is None
        and "file has more than 9 rows (FLEETPINN_MAX_UPLOAD_ROWS)" in error.reason
    )
    path.write_text(HEADER + ROW * 9 + ROW.rstrip())
    assert (
        "file has more than 9 rows (FLEETPINN_MAX_UPLOAD_ROWS)" in _refusal(path, max_rows=9).reason
    )


def test_bounds_hold_across_the_scan_s_chunks(tmp_path: Path) -> None:
    """A file of a few megabytes: the bad row lies past the first chunk, and rows are
    numbered across chunks."""
    path = tmp_path / "chunks.csv"
    rows = 100_000  # ~3.1 MB
    path.write_text(HEADER + ROW * rows + "H1,F2,2024-01-01T00:00:00Z,100,1\n")
    assert _refusal(path).row == rows + 1
    path.write_text(HEADER + ROW * rows)
    check_csv(path, "chunks.csv", max_rows=rows)


def _bomb(path: Path, row_groups: int) -> None:
    """row_groups x 1 M identical flights, dictionary-encoded and zstd: ~15 kB a row group."""
    rows = 1_000_000
    codes = pa.array(np.zeros(rows, dtype=np.int32))
    table = pa.table(
        {
            "tail": pa.DictionaryArray.from_arrays(codes, pa.array(["H1"])),
            "flight_id": pa.DictionaryArray.from_arrays(codes, pa.array(["F1"])),
            "flown_at": pa.DictionaryArray.from_arrays(codes, pa.array(["2024-01-01T00:00:00Z"])),
            "stress_range_mpa": pa.array(np.full(rows, 100.0)),
        }
    )
    with pq.ParquetWriter(path, table.schema, compression="zstd") as writer:
        for _ in range(row_groups):
            writer.write_table(table)


def test_a_parquet_decompression_bomb_is_refused_from_its_footer(tmp_path: Path) -> None:
    path = tmp_path / "bomb.parquet"
    _bomb(path, 50)
    assert path.stat().st_size < 1_000_000  # the probe's was 746 kB
    error = _refusal(path, max_rows=1_000_000)
    assert "file has 50000000 rows, more than 1000000" in error.reason


def test_a_parquet_file_s_decompressed_size_is_bounded(tmp_path: Path) -> None:
    path = tmp_path / "long.parquet"
    text = "x" * 2_000_000  # one compressible mission of 2 MB
    pq.write_table(pa.table({"tail": ["H1"], "mission": [text]}), path, compression="zstd")
    assert path.stat().st_size < 100_000
    error = _refusal(path, max_bytes=1_000_000)
    assert "bytes decompressed, at most 1000000" in error.reason
    assert read_table(path, max_bytes=3_000_000)["mission"].tolist() == [text]
