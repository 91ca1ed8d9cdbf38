from datetime import timedelta

import pytest
from fastapi.testclient import TestClient

from tests.app.conftest import START, add_tail


def _inspection(crack: float = 0.0051) -> dict[str, object]:
    return {
        "inspection_id": "I1",
        "inspected_at": (START + timedelta(days=2)).isoformat(),
        "crack_length_m": crack,
    }


def test_inspection_is_created_listed_and_idempotent(client: TestClient) -> None:
    add_tail(client, "N001", 8)
    created = client.post("/aircraft/N001/inspections", json=_inspection())
    assert created.status_code == 201
    assert created.json()["inserted"] == 1
    resend = client.post("/aircraft/N001/inspections", json=_inspection())
    assert resend.status_code == 200
    assert resend.json() == {
        "inserted": 0,
        "duplicates": 1,
        "aircraft_created": 0,
        "assessments": [],
    }
    listed = client.get("/aircraft/N001/inspections").json()
    assert listed == [
        {
            "inspection_id": "I1",
            "inspected_at": "2024-01-03T00:00:00Z",
            "crack_length_m": 0.0051,
            "detected": True,
            "detection_threshold_m": None,
            "pod_a50_m": None,
            "pod_a90_m": None,
            "repaired": False,
            "crack_after_repair_m": None,
            "location": "default",  # issue 20: every inspection names its control point
            # no active model: nothing to compare with
            "forecast_crack_m": None,
            "forecast_z": None,
            "flagged": False,
            "recorded_by": "test-admin",
        }
    ]


def test_inspection_conflict_and_validation(client: TestClient) -> None:
    add_tail(client, "N001", 8)
    client.post("/aircraft/N001/inspections", json=_inspection())
    conflict = client.post("/aircraft/N001/inspections", json=_inspection(0.006))
    assert conflict.status_code == 409
    assert "I1" in conflict.json()["detail"]
    invalid = client.post("/aircraft/N001/inspections", json=_inspection(0.0))
    assert invalid.status_code == 422
    assert invalid.json()["column"] == "crack_length_m"
    assert client.post("/aircraft/GHOST/inspections", json=_inspection()).status_code == 404
    assert client.get("/aircraft/GHOST/inspections").status_code == 404


def test_non_detections_and_repairs_are_stored_and_listed(client: TestClient) -> None:
    add_tail(client, "N001", 8)
    at = (START + timedelta(days=1)).isoformat()
    body = [
        {
            "inspection_id": "T",
            "inspected_at": at,
            "detected": False,
            "detection_threshold_m": 0.002,
        },
        {
            "inspection_id": "P",
            "inspected_at": at,
            "detected": False,
            "pod_a50_m": 0.001,
            "pod_a90_m": 0.003,
        },
        {
            "inspection_id": "R",
            "inspected_at": at,
            "crack_length_m": 0.006,
            "repaired": True,
            "crack_after_repair_m": 0.001,
        },
    ]
    assert client.post("/aircraft/N001/inspections", json=body).status_code == 201
    again = client.post("/aircraft/N001/inspections", json=body)
    assert again.json() == {
        "inserted": 0,
        "duplicates": 3,
        "aircraft_created": 0,
        "assessments": [],
    }
    listed = {i["inspection_id"]: i for i in client.get("/aircraft/N001/inspections").json()}
    assert listed["T"]["detected"] is False
    assert listed["T"]["crack_length_m"] is None
    assert listed["T"]["detection_threshold_m"] == 0.002
    assert (listed["P"]["pod_a50_m"], listed["P"]["pod_a90_m"]) == (0.001, 0.003)
    assert listed["R"]["repaired"] is True
    assert listed["R"]["crack_after_repair_m"] == 0.001
    assert listed["R"]["detected"] is True


@pytest.mark.parametrize(
    ("fields", "column"),
    [
        ({"detected": False}, "detection_threshold_m"),
        ({"detected": False, "pod_a50_m": 0.003, "pod_a90_m": 0.002}, "pod_a90_m"),
        ({"detected": False, "pod_a50_m": 0.003, "pod_a90_m": 0.003}, "pod_a90_m"),
        (
            {"detected": False, "crack_length_m": 0.004, "detection_threshold_m": 0.002},
            "crack_length_m",
        ),
        ({"crack_length_m": None}, "crack_length_m"),
        ({"crack_length_m": 0.004, "repaired": True}, "crack_after_repair_m"),
        ({"crack_length_m": 0.004, "crack_after_repair_m": 0.001}, "crack_after_repair_m"),
        ({"crack_length_m": 0.004, "detection_threshold_m": 0.002}, "detected"),
    ],
)
def test_inspection_combinations_are_checked(
    client: TestClient, fields: dict[str, object], column: str
) -> None:
    add_tail(client, "N001", 8)
    good = _inspection() | {"inspection_id": "OK"}
    bad = {"inspection_id": "BAD", "inspected_at": good["inspected_at"], **fields}
    answer = client.post("/aircraft/N001/inspections", json=[good, bad])
    assert answer.status_code == 422, answer.text
    assert answer.json()["column"] == column
    assert answer.json()["row"] == 2
    assert column in answer.json()["detail"]
    assert client.get("/aircraft/N001/inspections").json() == []  # nothing stored
