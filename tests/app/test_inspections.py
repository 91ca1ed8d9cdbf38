from datetime import timedelta

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
    assert resend.json() == {"inserted": 0, "duplicates": 1, "aircraft_created": 0}
    listed = client.get("/aircraft/N001/inspections").json()
    assert listed == [
        {"inspection_id": "I1", "inspected_at": "2024-01-03T00:00:00Z", "crack_length_m": 0.0051}
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
