"""Rules spanning several fields are stated in the published schema (app.schema_rules): a body
the schema takes is not refused for one of them, and one it refuses is a 422.  schemathesis'
positive data found a flight with two load forms, a location with both geometry forms and a
planned mix with every share 0 schema-valid, each answered 422."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import jsonschema_rs
import pytest
from fastapi.testclient import TestClient

from tests.app.conftest import flights, serving, settings_in

TABLE = {"crack_length_m": [0.002, 0.05], "factor": [1.12, 1.4]}
AT = "2024-03-01T00:00:00Z"


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """Tail R1 with 10 flights; no model (a planned forecast that passes validation is 409)."""
    with serving(settings_in(Path(tmp_path_factory.mktemp("rules")))) as test_client:
        assert test_client.put("/aircraft/R1").status_code == 201
        assert test_client.post("/aircraft/R1/flights", json=flights(10)).status_code == 201
        yield test_client


def _validator(client: TestClient, component: str, array: bool = False) -> Any:
    document = client.get("/openapi.json").json()
    item = {"$ref": f"#/components/schemas/{component}"}
    root = {"type": "array", "items": item} if array else item
    return jsonschema_rs.validator_for({**root, "components": document["components"]})


def _flight(number: int, **loads: Any) -> dict[str, Any]:
    return {"flight_id": f"R{number}", "flown_at": f"2024-03-01T{number:02d}:00:00Z", **loads}


FLIGHTS = [
    (_flight(1, stress_range_mpa=100.0), True),
    (_flight(2, cycles=[{"stress_range_mpa": 90.0, "load_ratio": 0.1}]), True),
    (_flight(3, stress_history_mpa=[0.0, 120.0, 10.0, 80.0]), True),
    (_flight(4, stress_range_mpa=100.0, cycles=[{"stress_range_mpa": 90.0}]), False),
    (_flight(5, stress_range_mpa=100.0, stress_history_mpa=None), True),
    (_flight(6), False),
    (_flight(7, stress_history_mpa=[120.0]), False),  # a history needs two points
    (_flight(8, cycles=[]), False),
]


@pytest.mark.parametrize(("flight", "valid"), FLIGHTS)
def test_a_flight_gives_exactly_one_load_form(
    client: TestClient, flight: dict[str, Any], valid: bool
) -> None:
    assert _validator(client, "FlightIn", array=True).is_valid([flight]) == valid
    answer = client.post("/aircraft/R1/flights", json=[flight])
    assert answer.status_code == (201 if valid else 422), answer.text


LOCATIONS = [
    ({"geometry_factor": 1.1}, True),
    ({"geometry_table": TABLE}, True),
    ({"geometry_factor": 1.1, "geometry_table": TABLE}, False),
    ({"geometry_factor": None, "geometry_table": TABLE}, True),
    ({"limit_stress_mpa": 200.0}, False),
    ({"critical_crack_m": 0.04, "geometry_factor": 1.2}, True),
]


@pytest.mark.parametrize(("entry", "valid"), LOCATIONS)
def test_a_location_gives_one_geometry_and_a_limit_stress_with_a_crack_case(
    client: TestClient, entry: dict[str, Any], valid: bool
) -> None:
    assert _validator(client, "LocationIn").is_valid(entry) == valid
    answer = client.put("/locations/rules", json=entry)
    assert answer.status_code in ((200, 201) if valid else (422,)), answer.text


@pytest.mark.parametrize(("shares", "valid"), [([0.0, 0.0], False), ([0.0, 1.0], True)])
def test_a_planned_mix_has_some_share(client: TestClient, shares: list[float], valid: bool) -> None:
    missions = [{"stress_range_mpa": 90.0 + n, "share": share} for n, share in enumerate(shares)]
    body = {"planned": {"flights_per_day": 4.0, "missions": missions}}
    assert _validator(client, "ForecastIn").is_valid(body) == valid
    answer = client.post("/aircraft/R1/forecast", json=body)
    assert answer.status_code == (409 if valid else 422), answer.text  # 409: no model yet


def _inspection(number: int, **fields: Any) -> dict[str, Any]:
    return {
        "inspection_id": f"RI{number}",
        "inspected_at": f"2024-01-0{number}T12:00:00Z",
        **fields,
    }


INSPECTIONS = [
    (_inspection(1, crack_length_m=0.005), True),
    (_inspection(2), False),  # detected (the default) without a crack
    (_inspection(3, crack_length_m=0.005, detection_threshold_m=0.001), False),
    (_inspection(4, detected=False, detection_threshold_m=0.001), True),
    (_inspection(5, detected=False, pod_a50_m=0.001, pod_a90_m=0.002), True),
    (_inspection(6, detected=False, detection_threshold_m=0.001, pod_a50_m=0.001), False),
    (_inspection(7, detected=False, pod_a50_m=0.001), False),
    (_inspection(8, crack_length_m=0.005, repaired=True), False),
    (_inspection(9, crack_length_m=0.005, repaired=True, crack_after_repair_m=0.001), True),
]


@pytest.mark.parametrize(("inspection", "valid"), INSPECTIONS)
def test_an_inspection_is_a_finding_a_threshold_or_a_pod_curve(
    client: TestClient, inspection: dict[str, Any], valid: bool
) -> None:
    assert _validator(client, "InspectionIn").is_valid(inspection) == valid
    answer = client.post("/aircraft/R1/inspections", json=inspection)
    assert answer.status_code == (201 if valid else 422), answer.text
