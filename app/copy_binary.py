"""PostgreSQL's binary COPY format built column-wise with numpy, a block of rows at a time.

psycopg's write_row formats one row per call: for 2.19 M flights that was ~3.5 s of Python
(cProfile), as long as the server took to store them.  Here each block is one numpy buffer:
per-row lengths give every field's offset, fixed-width values are scattered as big-endian bytes,
text as its UTF-8 bytes (from an Arrow string array) and bytea as its bytes (an Arrow binary
array: bytea's binary send form is the bytes themselves).  Format (PostgreSQL docs, COPY,
"Binary Format"): a signature, then per row an int16 field count and per field an int32 byte
length (-1: NULL) and the value in the type's binary send form; an int16 -1 ends the data.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa

SIGNATURE = b"PGCOPY\n\xff\r\n\x00" + bytes(8)  # then int32 flags and header extension length
TRAILER = b"\xff\xff"

# Wire type -> big-endian numpy dtype of its binary send form (text is handled apart).
FIXED: dict[str, str] = {"int8": ">i8", "int4": ">i4", "float8": ">f8", "bool": "u1"}
# Wire type -> the Arrow type whose buffers hold its values' bytes back to back.
VARIABLE: dict[str, pa.DataType] = {"text": pa.large_string(), "bytea": pa.large_binary()}
_MASKED = {"int8": "Int64", "int4": "Int32", "float8": "Float64", "bool": "boolean"}
BLOCK_ROWS = 200_000


def blocks(
    columns: Sequence[Sequence[Any]], wire: Sequence[str], block_rows: int = BLOCK_ROWS
) -> Iterator[bytes]:
    """The COPY data of equally long columns (None: NULL) as wire types `wire` ("int8", "int4",
    "float8", "bool", "text", "bytea"), signature first and trailer last, in blocks of block_rows rows.

    Raises ValueError for an unknown wire type.
    """
    unknown = set(wire) - {*FIXED, *VARIABLE}
    if unknown:
        raise ValueError(f"wire types must be among {sorted({*FIXED, *VARIABLE})}, not {unknown}")
    yield SIGNATURE
    n = len(columns[0]) if columns else 0
    for start in range(0, n, block_rows):
        part = [column[start : start + block_rows] for column in columns]
        yield _block(part, wire)
    yield TRAILER


def _block(columns: Sequence[Sequence[Any]], wire: Sequence[str]) -> bytes:
    fields = [_field(column, kind) for column, kind in zip(columns, wire, strict=True)]
    n = len(columns[0])
    widths = [4 + lengths for lengths, _, _ in fields]  # (rows,) each: length word + value
    row_start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(2 + np.sum(widths, axis=0), out=row_start[1:])
    buf = np.empty(int(row_start[-1]), dtype=np.uint8)
    starts = row_start[:-1]
    _scatter(buf, starts, np.full(n, len(fields), dtype=">i2"))
    position = starts + 2
    for (lengths, present, write), width in zip(fields, widths, strict=True):
        _scatter(buf, position, np.where(present, lengths, -1).astype(">i4"))  # NULL: -1
        write(buf, position + 4)
        position = position + width
    return buf.tobytes()


def _scatter(buf: np.ndarray, at: np.ndarray, values: np.ndarray) -> None:
    """Write each value's bytes at its offset (values: a fixed-width numpy array, rows long)."""
    size = values.dtype.itemsize
    as_bytes = values.view(np.uint8).reshape(-1, size)
    for k in range(size):  # one 1-D scatter per byte: no (rows, size) index array is built
        buf[at + k] = as_bytes[:, k]


Writer = Callable[[np.ndarray, np.ndarray], None]  # (buf, offsets): the values' bytes there
Field = tuple[np.ndarray, np.ndarray, Writer]  # byte lengths (0: NULL), not-NULL mask, writer


def _field(column: Sequence[Any], kind: str) -> Field:
    """Per-row byte lengths of the values, which are not NULL, and a writer of their bytes."""
    if kind in VARIABLE:
        return _variable(column, VARIABLE[kind])
    # pandas' masked arrays: None is NULL and integers stay exact (no detour through float).
    masked = pd.Series(column, dtype=_MASKED[kind], copy=False)
    present = masked.notna().to_numpy()
    dtype = np.dtype(FIXED[kind])
    values = masked.to_numpy(dtype=dtype.newbyteorder("="), na_value=0).astype(dtype)
    lengths = np.where(present, dtype.itemsize, 0)

    def write(buf: np.ndarray, at: np.ndarray) -> None:
        _scatter(buf, at[present], values[present])

    return lengths, present, write


def _variable(column: Sequence[Any], arrow_type: pa.DataType) -> Field:
    """Text's UTF-8 bytes, or bytea's bytes, from an Arrow array: its offsets give every length
    at once; an empty value is a zero-length value, not NULL."""
    strings = pa.array(column, type=arrow_type, from_pandas=True)  # NaN, None: NULL
    if isinstance(strings, pa.ChunkedArray):  # from pandas' Arrow-backed strings
        strings = strings.combine_chunks()
    _, offsets_buffer, data_buffer = strings.buffers()
    offsets = np.frombuffer(offsets_buffer, dtype=np.int64)[strings.offset :][: len(strings) + 1]
    data = np.frombuffer(data_buffer, dtype=np.uint8) if data_buffer is not None else None
    sizes = np.diff(offsets)
    present = strings.is_valid().to_numpy(zero_copy_only=False)

    def write(buf: np.ndarray, at: np.ndarray) -> None:
        total = int(sizes.sum())
        if total == 0 or data is None:
            return
        source = np.repeat(at - (offsets[:-1] - offsets[0]), sizes)
        buf[source + np.arange(total)] = data[offsets[0] : offsets[0] + total]

    return sizes, present, write
