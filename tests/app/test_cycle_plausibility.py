"""The plausible stress range bounds each cycle, not a flight's damage-equivalent range (issue
42: that range sums a flight's cycles, so 1,000 cycles of 200 MPa, 2,000 MPa under Paris with
m = 3, were refused as implausible); app.services.records.plausibility."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pandas as pd
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from tests.app.conftest import serving, settings_in

LIMIT = "must be <= 1000 MPa (FLEETPINN_MAX_STRESS_RANGE_MPA)"


@pytest.fixture(scope="module")
def settings(tmp_path_factory: pytest.TempPathFactory) -> Settings:
    return settings_in(Path(tmp_path_factory.mktemp("cycle-bound")))


@pytest.fixture(scope="module")
def client(settings: Settings) -> Iterator[TestClient]:
    with serving(settings) as test_client:
        assert test_client.put("/aircraft/C1").status_code == 201
        yield test_client


def _flight(flight_id: str, **loads: Any) -> dict[str, Any]:
    return {
        "flight_id": flight_id,
        "flown_at": f"2024-02-{int(flight_id[1:]):02d}T00:00:00Z",
        **loads,
    }


def _count(client: TestClient, tail: str = "C1") -> int:
    answer = client.get(f"/aircraft/{tail}")
    return int(answer.json()["flight_count"]) if answer.status_code == 200 else 0


def test_a_flight_of_1000_cycles_at_200_mpa_is_stored_with_its_damage(
    client: TestClient, settings: Settings
) -> None:
    cycles = [{"stress_range_mpa": 200.0, "load_ratio": 0.1}] * 1000
    answer = client.post("/aircraft/C1/flights", json=[_flight("F1", cycles=cycles)])
    assert answer.status_code == 201, answer.text
    # Paris: (sum n dS^m)^(1/m), 200 MPa x 1000^(1/m), above the per-cycle bound
    m = settings.law().m
    stored = client.get("/aircraft/C1/flights/F1").json()["stress_range_mpa"]
    assert stored == pytest.approx(200.0 * 1000 ** (1 / m), rel=1e-12)
    assert stored > 1000.0
    # a correction of its other values is checked against the same bound, and passes
    assert client.patch("/aircraft/C1/flights/F1", json={"mission": "M2"}).status_code == 200
    # the same as a history, rainflow counting its cycles
    history = [0.0, 200.0] * 1000 + [0.0]
    answer = client.post("/aircraft/C1/flights", json=[_flight("F2", stress_history_mpa=history)])
    assert answer.status_code == 201, answer.text
    assert client.get("/aircraft/C1/flights/F2").json()["stress_range_mpa"] > 1000.0


def test_a_cycle_file_of_1000_cycles_at_200_mpa_is_stored(
    client: TestClient, settings: Settings
) -> None:
    rows = pd.DataFrame(
        {
            "tail": "C2",
            "flight_id": "F1",
            "flown_at": "2024-02-01T00:00:00Z",
            "stress_range_mpa": [200.0] * 1000,
            "load_ratio": 0.1,
            "count": 1.0,
        }
    )
    files = {"file": ("cycles.csv", rows.to_csv(index=False).encode(), "text/csv")}
    answer = client.post("/flights/upload", files=files)
    assert answer.status_code == 201, answer.text
    stored = client.get("/aircraft/C2/flights/F1").json()["stress_range_mpa"]
    assert stored == pytest.approx(200.0 * 1000 ** (1 / settings.law().m), rel=1e-12)


@pytest.mark.parametrize(
    ("loads", "column", "words"),
    [
        (
            {
                "cycles": [
                    {"stress_range_mpa": 100.0, "load_ratio": 0.1},
                    {"stress_range_mpa": 1200.0, "load_ratio": 0.1},
                ]
            },
            "cycles[1].stress_range_mpa",
            "got 1200.0",
        ),
        (
            {"cycles": [{"max_stress_mpa": 1250.0, "min_stress_mpa": 50.0}]},
            "cycles[0]",
            "got 1200.0 (max_stress_mpa - min_stress_mpa)",
        ),
        ({"stress_history_mpa": [0.0, 1200.0, 0.0]}, "stress_history_mpa", "(counted by rainflow)"),
        ({"stress_range_mpa": 1200.0}, "stress_range_mpa", "got 1200.0"),
    ],
)
def test_a_single_cycle_of_1200_mpa_is_refused_naming_the_row_and_field(
    client: TestClient, loads: dict[str, Any], column: str, words: str
) -> None:
    before = _count(client)
    batch = [_flight("F10", stress_range_mpa=100.0), _flight("F11", **loads)]
    answer = client.post("/aircraft/C1/flights", json=batch)
    assert answer.status_code == 422, answer.text
    body = answer.json()
    assert (body["source"], body["row"], body["column"]) == ("body", 2, column)
    assert LIMIT in body["reason"] and words in body["reason"], body["reason"]
    assert _count(client) == before


def test_a_cycle_file_row_of_1200_mpa_is_refused_naming_it(client: TestClient) -> None:
    rows = pd.DataFrame(
        {
            "tail": "C3",
            "flight_id": ["F1", "F1", "F2"],
            "flown_at": ["2024-02-01T00:00:00Z"] * 2 + ["2024-02-02T00:00:00Z"],
            "stress_range_mpa": [200.0, 150.0, 1200.0],
            "load_ratio": 0.1,
            "count": 1.0,
        }
    )
    files = {"file": ("cycles.csv", rows.to_csv(index=False).encode(), "text/csv")}
    answer = client.post("/flights/upload", files=files)
    assert answer.status_code == 422, answer.text
    body = answer.json()
    assert (body["source"], body["row"], body["column"]) == ("cycles.csv", 3, "stress_range_mpa")
    assert LIMIT in body["reason"] and "got 1200.0" in body["reason"]
    assert _count(client, "C3") == 0
