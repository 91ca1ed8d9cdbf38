"""Uploaded record files: read with the offline CLI's reader (model.records) from a local copy,
its shape checked before it is parsed (model.record_bounds) and its rows bounded by
max_upload_rows, whatever the compression of a Parquet file."""

from __future__ import annotations

import codecs
import shutil
import tempfile
from pathlib import Path
from typing import IO

import pandas as pd

from model.records import RecordError, read_table


def upload_name(filename: str | None) -> str:
    """The client's file name without any directory part, to label errors."""
    return Path(filename or "").name or "upload"


def read_upload(
    filename: str | None, upload: IO[bytes], *, max_rows: int, max_bytes: int
) -> pd.DataFrame:
    """Read an uploaded CSV or Parquet file with the offline CLI's reader (model.records).

    The type comes from the file name's suffix, else from the content (Parquet's magic bytes).
    At most max_rows rows, and a Parquet file at most max_bytes decompressed (its footer says
    before a page is read).  Raises RecordError named after the uploaded file.
    """
    name = upload_name(filename)
    suffix = Path(name).suffix.lower()
    head = upload.read(_HEAD_BYTES)
    upload.seek(0)
    if suffix not in (".csv", ".parquet"):
        suffix = ".parquet" if head[:4] == b"PAR1" else ".csv"
    if suffix == ".csv" and not _utf8_text(head):
        raise RecordError(name, None, None, _NOT_UTF8)
    with tempfile.TemporaryDirectory(prefix="fleetpinn-upload-") as folder:
        # A fixed local name: the client's file name only labels errors.
        path = Path(folder) / f"upload{suffix}"
        with path.open("wb") as out:
            shutil.copyfileobj(upload, out, length=1 << 20)
        try:
            return read_table(path, max_rows=max_rows, max_bytes=max_bytes)
        except RecordError as exc:
            # bytes past the head that are no UTF-8 text: the reader's decoder message would
            # name a byte offset and a codec, not the problem
            undecodable = isinstance(exc.__cause__, UnicodeDecodeError) or "UTF8" in exc.reason
            reason = _NOT_UTF8 if suffix == ".csv" and undecodable else exc.reason
            raise RecordError(name, exc.row, exc.column, reason) from exc


# How much of an upload is looked at before it is read: enough to tell an image or an archive
# sent as CSV from text.
_HEAD_BYTES = 64 * 1024
_NOT_UTF8 = "not a UTF-8 CSV file (send CSV text in UTF-8, or a .parquet file)"


def _utf8_text(head: bytes) -> bool:
    """Whether the first bytes of a file are UTF-8 text (a character cut at the end allowed);
    a NUL byte marks binary data even where it decodes."""
    if b"\x00" in head:
        return False
    try:
        codecs.getincrementaldecoder("utf-8")().decode(head, final=False)
    except UnicodeDecodeError:
        return False
    return True
