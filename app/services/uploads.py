"""Uploaded record files: read with the offline CLI's reader (model.records) from a local copy,
after a look at a CSV's header line (a header of a million columns read as an "empty file")."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path
from typing import IO

import pandas as pd

from model.records import RecordError, read_table

# A record file's header: the contract's few columns and some to spare (model.records).
_MAX_COLUMNS = 256
_MAX_HEADER_BYTES = 64 * 1024


def upload_name(filename: str | None) -> str:
    """The client's file name without any directory part, to label errors."""
    return Path(filename or "").name or "upload"


def read_upload(filename: str | None, upload: IO[bytes]) -> pd.DataFrame:
    """Read an uploaded CSV or Parquet file with the offline CLI's reader (model.records).

    The type comes from the file name's suffix, else from the content (Parquet's magic bytes).
    Raises RecordError named after the uploaded file.
    """
    name = upload_name(filename)
    suffix = Path(name).suffix.lower()
    if suffix not in (".csv", ".parquet"):
        head = upload.read(4)
        upload.seek(0)
        suffix = ".parquet" if head == b"PAR1" else ".csv"
    with tempfile.TemporaryDirectory(prefix="fleetpinn-upload-") as folder:
        # A fixed local name: the client's file name only labels errors.
        path = Path(folder) / f"upload{suffix}"
        with path.open("wb") as out:
            shutil.copyfileobj(upload, out, length=1 << 20)
        if suffix == ".csv":
            _check_header(path, name)
        try:
            return read_table(path)
        except RecordError as exc:
            raise RecordError(name, exc.row, exc.column, exc.reason) from exc


def _check_header(path: Path, name: str) -> None:
    """Refuse a CSV whose header line is longer than _MAX_HEADER_BYTES or names more than
    _MAX_COLUMNS columns (the reader would take it for an empty file, or hold every column)."""
    with path.open("rb") as file:
        head = file.read(_MAX_HEADER_BYTES + 1)
    line, newline, _ = head.partition(b"\n")
    if not newline and len(head) > _MAX_HEADER_BYTES:
        raise RecordError(
            name,
            None,
            None,
            f"header line longer than {_MAX_HEADER_BYTES} bytes (at most {_MAX_COLUMNS} "
            "columns are read): is this a flights file?",
        )
    columns = line.count(b",") + 1
    if columns > _MAX_COLUMNS:
        raise RecordError(
            name,
            None,
            None,
            f"header names {columns} columns, at most {_MAX_COLUMNS}: is this a flights file?",
        )
