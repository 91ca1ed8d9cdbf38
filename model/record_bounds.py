"""The shape of a record file, checked before a reader parses it (model.records.read_table).

A reader given a hostile shape spends time and memory before it can refuse it: pandas read one
CSV row of 40,000 extra fields as an index of 40,000 levels (31 s), and 746 kB of zstd Parquet
decompressed to 50 M rows (2.5 GiB).  So a CSV is scanned first, a megabyte at a time with
numpy (about 0.1 s per 100 MB): every line at most MAX_LINE_BYTES long, no row with more fields
than the header, at most MAX_COLUMNS columns, and optionally at most max_rows rows; a Parquet
file's footer gives its columns, rows and decompressed size before a page is read.

Rows are 1-based data rows as in model.records: row 1 is the line after the header.
"""

from __future__ import annotations

import csv
import struct
from pathlib import Path
from typing import BinaryIO

import numpy as np
import pyarrow.parquet as pq

from model.record_errors import RecordError

# A record file's header: the contract's few columns and some to spare.
MAX_COLUMNS = 256
# Any line of a CSV: a header of MAX_COLUMNS names, or a row of MAX_COLUMNS fields of up to
# 256 bytes each, far more than a tail, an id, a time and a few numbers need.
MAX_LINE_BYTES = 64 * 1024
# A Parquet footer (its schema and row groups' statistics): a record file's is a few kB.
MAX_PARQUET_FOOTER_BYTES = 16 * 1024 * 1024

_CHUNK_BYTES = 1 << 20
_NEWLINE, _COMMA = ord("\n"), ord(",")


def check_csv(path: Path, source: str, max_rows: int | None = None) -> None:
    """Raise RecordError unless every line of the CSV at `path` is at most MAX_LINE_BYTES long,
    its header names at most MAX_COLUMNS columns, no row has more fields than the header, and
    (max_rows given) it holds at most max_rows non-blank rows.  The first offending row is
    named.  Fields are counted by commas; a line with too many is read by the csv module, so
    that a quoted comma is not counted."""
    with path.open("rb") as file:
        header = _header(file.read(MAX_LINE_BYTES + 1), source)
        file.seek(len(header) + 1)
        _check_rows(file, source, _fields(header), max_rows)


def check_parquet(
    path: Path, source: str, max_rows: int | None = None, max_bytes: int | None = None
) -> None:
    """Raise RecordError unless the Parquet file's footer (read alone, at most
    MAX_PARQUET_FOOTER_BYTES) states at most MAX_COLUMNS columns, max_rows rows and max_bytes
    bytes decompressed (the row groups' total_byte_size), each bound checked where given.  A
    file that is no Parquet file is left to the reader, which says so."""
    size = path.stat().st_size
    with path.open("rb") as file:
        if size < 12 or file.read(4) != b"PAR1":
            return
        file.seek(size - 8)
        tail = file.read(8)
    footer_bytes = struct.unpack("<I", tail[:4])[0]
    if tail[4:] != b"PAR1":
        return
    if footer_bytes > MAX_PARQUET_FOOTER_BYTES:
        raise RecordError(
            source,
            None,
            None,
            f"Parquet footer of {footer_bytes} bytes, at most {MAX_PARQUET_FOOTER_BYTES}: "
            "is this a record file?",
        )
    try:
        metadata = pq.read_metadata(path)
    except Exception as exc:  # reader errors carry no stable type; report them on the file
        raise RecordError(source, None, None, f"cannot read file: {exc}") from exc
    if metadata.num_columns > MAX_COLUMNS:
        raise RecordError(
            source,
            None,
            None,
            f"file has {metadata.num_columns} columns, at most {MAX_COLUMNS}: "
            "is this a record file?",
        )
    if max_rows is not None and metadata.num_rows > max_rows:
        raise RecordError(source, None, None, _too_many_rows(metadata.num_rows, max_rows))
    if max_bytes is not None:
        decompressed = sum(
            metadata.row_group(group).total_byte_size for group in range(metadata.num_row_groups)
        )
        if decompressed > max_bytes:
            raise RecordError(
                source,
                None,
                None,
                f"holds {decompressed} bytes decompressed, at most {max_bytes} "
                "(FLEETPINN_MAX_UPLOAD_BYTES; compression does not raise the limit)",
            )


def _too_many_rows(rows: int | None, max_rows: int) -> str:
    """rows: the file's count where known (a Parquet footer), None where the scan stopped."""
    found = f"more than {max_rows} rows" if rows is None else f"{rows} rows, more than {max_rows}"
    return f"file has {found} (FLEETPINN_MAX_UPLOAD_ROWS): split it"


def _header(head: bytes, source: str) -> bytes:
    """The header line (without its newline) of a CSV starting with `head`."""
    line, newline, _ = head.partition(b"\n")
    if not newline and len(head) > MAX_LINE_BYTES:
        raise RecordError(
            source,
            None,
            None,
            f"header line longer than {MAX_LINE_BYTES} bytes (at most {MAX_COLUMNS} "
            "columns are read): is this a record file?",
        )
    columns = _fields(line)
    if columns > MAX_COLUMNS:
        raise RecordError(
            source,
            None,
            None,
            f"header names {columns} columns, at most {MAX_COLUMNS}: is this a record file?",
        )
    return line


def _fields(line: bytes) -> int:
    """The number of fields of one CSV line, its quoting understood."""
    if b'"' not in line:
        return line.count(b",") + 1
    try:
        parsed = next(csv.reader([line.decode("utf-8").rstrip("\r")]), [])
    except (UnicodeDecodeError, csv.Error):
        return line.count(b",") + 1  # the reader will name what is wrong with it
    return max(len(parsed), 1)


def _check_rows(file: BinaryIO, source: str, fields: int, max_rows: int | None) -> None:
    """Scan the lines after the header a chunk at a time, each chunk after the unfinished line
    of the one before (at most MAX_LINE_BYTES): a line's length is the distance between its
    newlines, its commas those between them."""
    carry = b""
    row = 0  # data rows ended so far, blank ones included (a reader's row numbers)
    rows = 0  # non-blank ones
    while more := file.read(_CHUNK_BYTES):
        buffer = carry + more
        data = np.frombuffer(buffer, dtype=np.uint8)
        ends = np.flatnonzero(data == _NEWLINE)
        if len(ends):
            starts = np.concatenate(([0], ends[:-1] + 1))
            lengths = ends - starts
            commas = np.flatnonzero(data == _COMMA)
            comma_counts = np.diff(np.searchsorted(commas, ends), prepend=0)
            for index in np.flatnonzero((lengths > MAX_LINE_BYTES) | (comma_counts >= fields)):
                line = buffer[starts[index] : ends[index]]
                _check_line(line, source, row + int(index) + 1, fields)
            row += len(ends)
            rows += int(np.count_nonzero(lengths))
            if max_rows is not None and rows > max_rows:
                raise RecordError(source, None, None, _too_many_rows(None, max_rows))
            carry = buffer[int(ends[-1]) + 1 :]
        else:
            carry = buffer
        if len(carry) > MAX_LINE_BYTES:
            _check_line(carry, source, row + 1, fields, unfinished=True)
    if carry:  # the last line, without a newline
        _check_line(carry, source, row + 1, fields)
        if max_rows is not None and rows + 1 > max_rows:
            raise RecordError(source, None, None, _too_many_rows(None, max_rows))


def _check_line(line: bytes, source: str, row: int, fields: int, unfinished: bool = False) -> None:
    """Raise RecordError naming `row` when the line has more fields than the header or is
    longer than MAX_LINE_BYTES (of a line not yet ended, the part read so far)."""
    found = _fields(line)
    at_least = "at least " if unfinished else ""
    if found > fields:
        reason = f"has {at_least}{found} fields, more than the header's {fields}"
        raise RecordError(source, row, None, reason)
    if len(line) > MAX_LINE_BYTES:
        reason = f"line of {at_least}{len(line)} bytes, at most {MAX_LINE_BYTES}"
        raise RecordError(source, row, None, reason)
