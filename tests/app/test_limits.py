"""Request limits (app.limits, app.config): each refused with a clear 413/422/503 that names the
setting, and nothing stored."""

from __future__ import annotations

from collections.abc import Iterator

import pandas as pd
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from tests.app.conftest import flights, serving


@pytest.fixture
def limited(settings: Settings) -> Iterator[TestClient]:
    small = settings.model_copy(
        update={"max_upload_bytes": 4096, "max_body_bytes": 2048, "max_batch_rows": 5}
    )
    with serving(small) as client:
        assert client.put("/aircraft/L1").status_code == 201
        yield client


def _flight_count(client: TestClient) -> int:
    count: int = client.get("/aircraft/L1").json()["flight_count"]
    return count


def test_an_upload_over_its_limit_is_413_and_stores_nothing(limited: TestClient) -> None:
    csv = pd.DataFrame([{"tail": "L1", **f} for f in flights(200)]).to_csv(index=False)
    assert len(csv) > 4096
    answer = limited.post("/flights/upload", files={"file": ("big.csv", csv, "text/csv")})
    assert answer.status_code == 413
    assert "max_upload_bytes" in answer.json()["detail"]
    assert _flight_count(limited) == 0
    small = pd.DataFrame([{"tail": "L1", **f} for f in flights(3)]).to_csv(index=False)
    answer = limited.post("/flights/upload", files={"file": ("small.csv", small, "text/csv")})
    assert answer.status_code == 201


def test_a_json_body_over_its_limit_is_413(limited: TestClient) -> None:
    answer = limited.post("/aircraft/L1/flights", json=flights(40))
    assert answer.status_code == 413
    assert "max_body_bytes" in answer.json()["detail"]
    assert _flight_count(limited) == 0


def test_a_chunked_body_is_counted_as_it_arrives(limited: TestClient) -> None:
    """No Content-Length to refuse up front: the body is refused once 2,048 bytes arrived."""

    def chunks() -> Iterator[bytes]:
        yield b"["
        for i in range(100):
            yield (
                (b"," if i else b"")
                + b'{"flight_id": "F%03d", "flown_at": "2024-01-01T00:00:00Z", "stress_range_mpa": 100}'
                % i
            )
        yield b"]"

    answer = limited.post(
        "/aircraft/L1/flights", content=chunks(), headers={"content-type": "application/json"}
    )
    assert answer.status_code == 413
    assert "max_body_bytes" in answer.json()["detail"]
    assert _flight_count(limited) == 0


def test_a_batch_over_max_batch_rows_is_422_naming_it(limited: TestClient) -> None:
    answer = limited.post("/aircraft/L1/flights", json=flights(6))
    assert answer.status_code == 422
    body = answer.json()
    assert body["source"] == "body" and "max_batch_rows" in body["reason"]
    assert _flight_count(limited) == 0
    assert limited.post("/aircraft/L1/flights", json=flights(5)).status_code == 201


@pytest.mark.parametrize(
    ("path", "field"),
    [
        ("/aircraft?limit=1001", "limit"),
        ("/jobs?limit=501", "limit"),
        ("/fleet/ranking?limit=0", "limit"),
    ],
)
def test_page_sizes_are_capped(limited: TestClient, path: str, field: str) -> None:
    answer = limited.get(path)
    assert answer.status_code == 422
    assert answer.json()["detail"][0]["loc"] == ["query", field]


def test_a_read_over_the_time_limit_is_503_and_probes_still_answer(settings: Settings) -> None:
    hasty = settings.model_copy(update={"request_timeout_seconds": 1e-4})
    with serving(hasty) as client:
        answer = client.get("/aircraft")
        assert answer.status_code == 503
        assert "request_timeout_seconds" in answer.json()["detail"]
        assert client.get("/health").status_code == 200
        # Writes are never cut short: they commit whole or not at all.
        assert client.put("/aircraft/T1").status_code == 201
