"""Error texts a user can act on: values as they were sent (no numpy reprs), malformed JSON
located by character (not called a row), binary data sent as CSV named as such."""

from __future__ import annotations

import struct
import zlib
from datetime import timedelta

from fastapi.testclient import TestClient

from tests.app.conftest import START, add_tail

# The start of a real PNG file: signature and an IHDR chunk of a 1x1 image.
_IHDR = struct.pack(">IIBBBBB", 1, 1, 8, 2, 0, 0, 0)
PNG = (
    b"\x89PNG\r\n\x1a\n"
    + struct.pack(">I", len(_IHDR))
    + b"IHDR"
    + _IHDR
    + struct.pack(">I", zlib.crc32(b"IHDR" + _IHDR))
)


def test_a_bad_value_reads_as_it_was_sent(client: TestClient) -> None:
    add_tail(client, "N1", 8)
    at = (START + timedelta(days=1)).isoformat()
    body = {"inspection_id": "I1", "inspected_at": at, "crack_length_m": 5.0}
    answer = client.post("/aircraft/N1/inspections", json=body)
    assert answer.status_code == 422
    error = answer.json()
    assert error["column"] == "crack_length_m"
    assert error["reason"].endswith("got 5.0"), error["reason"]
    assert "np." not in answer.text and "float64" not in answer.text
    flights = [{"flight_id": "X", "flown_at": at, "stress_range_mpa": 5000}]
    answer = client.post("/aircraft/N1/flights", json=flights)
    assert answer.status_code == 422
    assert answer.json()["reason"].endswith("got 5000.0")
    assert "np." not in answer.text


def test_malformed_json_is_located_by_character_not_row(client: TestClient) -> None:
    add_tail(client, "N1", 8)
    text = '[{"flight_id": "F1", "flown_at": }]'
    answer = client.post(
        "/aircraft/N1/flights", content=text, headers={"content-type": "application/json"}
    )
    assert answer.status_code == 422
    error = answer.json()
    assert error.get("row") is None and error.get("column") is None
    assert error["reason"].startswith(
        f"the body is not valid JSON at character {text.index('}') + 1}"
    )


def test_a_png_sent_as_csv_is_not_a_utf8_csv_file(client: TestClient) -> None:
    for name in ("flights.csv", "flights"):
        answer = client.post("/flights/upload", files={"file": (name, PNG + b"\x00" * 64)})
        assert answer.status_code == 422
        error = answer.json()
        assert error["source"] == name
        assert error["reason"].startswith("not a UTF-8 CSV file"), error
        assert "codec" not in answer.text and "decode" not in answer.text
    # bytes that are no UTF-8 past the first 64 KiB: the same words
    late = b"tail,flight_id,flown_at,stress_range_mpa\n" + b"A,1,2024-01-01,100\n" * 5000
    answer = client.post("/flights/upload", files={"file": ("late.csv", late + b"\xff\xfe\n")})
    assert answer.status_code == 422
    assert answer.json()["reason"].startswith("not a UTF-8 CSV file"), answer.json()
