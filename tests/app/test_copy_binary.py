"""app.copy_binary against PostgreSQL itself: the bytes it builds are the ones the server's own
binary COPY TO writes for the same rows (NULLs, empty and non-ASCII text, int64 extremes, -0.0,
blocks that split the rows), and they load back as the same values."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
import pytest
from sqlalchemy import create_engine

from app import copy_binary

WIRE = ["int4", "text", "float8", "bool", "int8", "bytea"]
COLUMNS: list[Any] = [
    np.array([1, -2, 2**31 - 1, 7, 0], dtype=np.int64),
    pd.Series(["a", "", None, "é\t\\x\n", np.nan], dtype="string[pyarrow]").array,
    pd.Series([1.5, np.nan, -0.0, 1e300, 5e-324]).array,
    [True, False, None, True, False],
    [2**62, -(2**63), None, 0, -1],
    [b"\x00\xff", b"", None, np.float64(1.5).tobytes(), b"\\x"],
]
ROWS = [
    (1, "a", 1.5, True, 2**62, b"\x00\xff"),
    (-2, "", None, False, -(2**63), b""),
    (2**31 - 1, None, -0.0, None, None, None),
    (7, "é\t\\x\n", 1e300, True, 0, np.float64(1.5).tobytes()),
    (0, None, 5e-324, False, -1, b"\\x"),
]


def test_text_from_python_objects_and_arrow_backed_strings_is_the_same() -> None:
    objects = [None, "a", "", "é", np.nan]
    arrow = pd.Series(objects, dtype="string[pyarrow]").array
    assert list(copy_binary.blocks([objects], ["text"])) == list(
        copy_binary.blocks([arrow], ["text"])
    )


def test_bytea_is_its_bytes_framed_by_their_length() -> None:
    """PostgreSQL's binary COPY (docs, "Binary Format"): per row an int16 field count, per
    field an int32 length (-1: NULL) and bytea's send form, the bytes themselves."""
    values = [b"\x01\x02\x03", None, b""]
    rows = [
        b"\x00\x01" + len(v).to_bytes(4, "big") + v if v is not None else b"\x00\x01" + b"\xff" * 4
        for v in values
    ]
    expected = copy_binary.SIGNATURE + b"".join(rows) + copy_binary.TRAILER
    assert b"".join(copy_binary.blocks([values], ["bytea"], block_rows=2)) == expected


def test_unknown_wire_types_are_refused() -> None:
    with pytest.raises(ValueError, match="wire types"):
        list(copy_binary.blocks([[1]], ["numeric"]))


@pytest.mark.parametrize("block_rows", [2, 5])
def test_blocks_are_what_postgresql_writes_and_load_back(
    database_url: str, block_rows: int
) -> None:
    if not database_url.startswith("postgresql"):
        pytest.skip("PostgreSQL's binary COPY format")
    engine = create_engine(database_url)
    try:
        with engine.connect() as connection:
            driver = connection.connection.driver_connection
            assert driver is not None
            cursor = driver.cursor()
            cursor.execute(
                "CREATE TEMPORARY TABLE t (a int4, b text, c float8, d bool, e int8, f bytea)"
            )
            ours = b"".join(copy_binary.blocks(COLUMNS, WIRE, block_rows=block_rows))
            with cursor.copy("COPY t FROM STDIN (FORMAT BINARY)") as copy:
                copy.write(ours)
            assert cursor.execute("SELECT * FROM t").fetchall() == ROWS
            with cursor.copy("COPY t TO STDOUT (FORMAT BINARY)") as copy:
                theirs = b"".join(bytes(block) for block in copy)
            assert ours == theirs
    finally:
        engine.dispose()
