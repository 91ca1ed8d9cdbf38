"""One request cannot break the catalogue: every PUT is validated before anything is stored
(strict numbers, the PoD pair together), and DELETE /locations/{name} removes an entry nothing
refers to, refuses one that records still refer to (saying which), or with force removes them
too; each delete is audited."""

from datetime import timedelta
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.app.conftest import START, add_tail

WING = {"stress_factor": 1.5, "initial_crack_m": 0.002, "critical_crack_m": 0.04}


@pytest.mark.parametrize(
    ("body", "field", "said"),
    [
        ({"pod_a50_m": 0.002}, "pod_a90_m", "pod_a90_m is missing"),
        ({"pod_a90_m": 0.003}, "pod_a90_m", "pod_a50_m is missing"),
        ({"stress_factor": "1.2"}, "stress_factor", "valid number"),
        ({"critical_crack_m": "0.04"}, "critical_crack_m", "valid number"),
        ({"growth_law": {"learn": "true"}}, "learn", "valid boolean"),
    ],
)
def test_a_bad_entry_is_a_422_naming_its_field_and_the_catalogue_still_answers(
    client: TestClient, body: dict[str, Any], field: str, said: str
) -> None:
    answer = client.put("/locations/x", json=body)
    assert answer.status_code == 422, answer.text
    detail = answer.json()["detail"][0]
    assert field in detail["loc"] and said in detail["msg"]
    assert client.get("/locations/x").status_code == 404
    listed = client.get("/locations")
    assert listed.status_code == 200
    assert [entry["name"] for entry in listed.json()] == ["default"]


def test_an_integer_is_a_number(client: TestClient) -> None:
    answer = client.put("/locations/x", json={"stress_factor": 2})
    assert answer.status_code == 201, answer.text
    assert answer.json()["stress_factor"] == 2.0


def test_an_entry_nothing_refers_to_is_deleted_and_audited(client: TestClient) -> None:
    assert client.put("/locations/wing-splice", json=WING).status_code == 201
    deleted = client.delete("/locations/wing-splice")
    assert deleted.status_code == 200, deleted.text
    assert deleted.json()["critical_crack_m"] == 0.04
    assert client.get("/locations/wing-splice").status_code == 404
    (event,) = client.get("/audit", params={"action": "location.delete"}).json()["items"]
    assert event["subject"] == "wing-splice"
    assert event["detail"]["entry"]["critical_crack_m"] == 0.04
    assert client.delete("/locations/wing-splice").status_code == 404


def test_an_entry_records_refer_to_is_refused_naming_them_unless_forced(
    client: TestClient,
) -> None:
    assert client.put("/locations/wing", json=WING).status_code == 201
    add_tail(client, "N1", 8)
    add_tail(client, "N2", 8)
    assert client.put("/aircraft/N1/locations", json={"locations": ["wing"]}).status_code == 200
    inspection = {
        "inspection_id": "W1",
        "inspected_at": (START + timedelta(days=1)).isoformat(),
        "crack_length_m": 0.0021,
        "location": "wing",
    }
    assert client.post("/aircraft/N2/inspections", json=inspection).status_code == 201
    refused = client.delete("/locations/wing")
    assert refused.status_code == 409
    detail = refused.json()["detail"]
    assert "1 aircraft list it (N1" in detail and "1 inspections are stored at it" in detail
    assert client.get("/locations/wing").status_code == 200  # nothing removed
    forced = client.delete("/locations/wing", params={"force": "true"})
    assert forced.status_code == 200, forced.text
    assert client.get("/locations/wing").status_code == 404
    assert client.get("/aircraft/N2/inspections").json() == []
    assert client.get("/aircraft/N1/locations").json()["locations"] == ["default"]
    (event,) = client.get("/audit", params={"action": "location.delete"}).json()["items"]
    assert event["detail"]["removed"]["inspections"] == 1
    assert event["detail"]["removed"]["tails_listing"] == ["N1"]


def test_the_default_location_is_never_deleted(client: TestClient) -> None:
    refused = client.delete("/locations/default", params={"force": "true"})
    assert refused.status_code == 409
    assert "cannot be deleted" in refused.json()["detail"]


def test_force_must_be_a_boolean(client: TestClient) -> None:
    assert client.put("/locations/wing", json=WING).status_code == 201
    assert client.delete("/locations/wing", params={"force": "maybe"}).status_code == 422


@pytest.mark.parametrize(
    ("law", "status", "said"),
    [
        ({"law": "walker", "paris_c": 1.5e-11, "paris_m": 3.8, "walker_gamma": 0.6}, 201, None),
        ({"law": "walker", "learn": True}, 201, None),
        ({"law": "paris", "paris_c": 1.5e-11, "paris_m": 3.8, "walker_gamma": 0.6}, 422, "Walker"),
        ({"law": "nasgro"}, 422, "NASGRO terms"),
        ({"law": "nasgro", "learn": True}, 422, "not the nasgro law"),
        ({"law": "walker"}, 422, "a material's constants"),
    ],
)
def test_a_location_has_its_own_growth_law(
    client: TestClient, law: dict[str, Any], status: int, said: str | None
) -> None:
    answer = client.put("/locations/x", json={"growth_law": law})
    assert answer.status_code == status, answer.text
    if said is None:
        stored = answer.json()["growth_law"]
        assert stored["law"] == law["law"] and stored["walker_gamma"] == law.get("walker_gamma")
        return
    detail = answer.json()["detail"][0]
    assert "growth_law" in detail["loc"] and said in detail["msg"]
    assert client.get("/locations/x").status_code == 404


def test_a_material_gives_a_walker_law_its_constants(client: TestClient) -> None:
    answer = client.put(
        "/locations/x", json={"material": "2024-T3", "growth_law": {"law": "walker"}}
    )
    assert answer.status_code == 201, answer.text
