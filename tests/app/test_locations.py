"""The catalogue of control points (PUT/GET /locations) and inspections that name one."""

from datetime import timedelta

import numpy as np
import pandas as pd
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import inspect as inspect_db
from sqlalchemy import text

from app import migrate
from app.config import Settings
from app.db import make_engine
from app.local_server import wait_for_job
from app.services.records.locations import StoredLocation, local_stress, physics
from app.tables import DEFAULT_LOCATION_ID
from model.geometry import GeometryTable
from model.materials import law_for
from tests.app.conftest import START, add_tail, inspect, serving

BEFORE_LOCATIONS = "3f6b8d2c1e57"

WING = {
    "description": "Lower wing splice",
    "stress_factor": 1.35,
    "stress_factor_by_mission": {"M3": 1.5},
    "geometry_table": {"crack_length_m": [0.002, 0.05], "factor": [1.12, 1.4]},
    "initial_crack_m": 0.00127,
    "critical_crack_m": 0.04,
    "material": "2024-T3",
    "growth_law": {"law": "paris", "paris_c": 1.5e-11, "paris_m": 3.8},
    "inspection_method": "eddy current",
    "sizing_relative_sd": 0.05,
    "pod_a50_m": 0.0015,
    "pod_a90_m": 0.0025,
}


def test_a_location_is_created_read_replaced_and_listed(client: TestClient) -> None:
    created = client.put("/locations/wing-splice", json=WING)
    assert created.status_code == 201, created.text
    body = created.json()
    law = {"law": "paris", "paris_c": 1.5e-11, "paris_m": 3.8, "walker_gamma": None, "learn": False}
    assert {k: body[k] for k in WING} == {**WING, "growth_law": law}
    assert body["name"] == "wing-splice"
    assert body["geometry_factor"] is None
    assert client.get("/locations/wing-splice").json() == body
    replaced = client.put("/locations/wing-splice", json={**WING, "stress_factor": 2.0})
    assert replaced.status_code == 200
    assert replaced.json()["stress_factor"] == 2.0
    names = [entry["name"] for entry in client.get("/locations").json()]
    assert names == ["default", "wing-splice"]
    default = client.get("/locations/default").json()
    # the migration's default location: factor 1 and the model's own physics
    assert default["stress_factor"] == 1.0
    assert default["initial_crack_m"] is None and default["growth_law"] is None
    assert client.get("/locations/nowhere").status_code == 404


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"initial_crack_m": 0.01, "critical_crack_m": 0.01}, "critical_crack_m"),
        ({"initial_crack_m": 0.02, "critical_crack_m": 0.01}, "critical_crack_m"),
        ({"pod_a50_m": 0.003, "pod_a90_m": 0.003}, "pod_a90_m"),
        ({"pod_a50_m": 0.003, "pod_a90_m": 0.002}, "pod_a90_m"),
        ({"stress_factor": 0}, "stress_factor"),
        ({"material": "unobtainium"}, "material"),
        ({"growth_law": {"law": "paris", "paris_c": 1e-11}}, "growth_law"),
        ({"geometry_factor": 1.1}, "geometry_table"),
        ({"geometry_table": {"crack_length_m": [0.01, 0.005], "factor": [1, 1]}}, "geometry_table"),
    ],
)
def test_a_bad_entry_is_refused_naming_its_field_and_nothing_is_stored(
    client: TestClient, change: dict[str, object], field: str
) -> None:
    answer = client.put("/locations/bad", json={**WING, **change})
    assert answer.status_code == 422, answer.text
    assert field in answer.json()["detail"][0]["loc"]
    assert client.get("/locations/bad").status_code == 404


@pytest.mark.parametrize(
    ("entry", "field"),
    [
        ({"initial_crack_m": 0.06}, "initial_crack_m"),
        ({"critical_crack_m": 0.004}, "critical_crack_m"),
    ],
)
def test_an_entry_contradicting_the_models_cracks_is_refused(
    client: TestClient, entry: dict[str, float], field: str
) -> None:
    """One crack given, the other the model's (a0 0.005 m, a_crit 0.05 m)."""
    answer = client.put("/locations/bad", json=entry)
    assert answer.status_code == 422, answer.text
    assert answer.json()["column"] == field
    assert client.get("/locations/bad").status_code == 404


def test_an_inspection_names_its_location_or_is_refused(client: TestClient) -> None:
    add_tail(client, "N1", 8)
    client.put("/locations/wing", json=WING)
    body = {
        "inspection_id": "W1",
        "inspected_at": (START + timedelta(days=1)).isoformat(),
        "crack_length_m": 0.002,
    }
    unknown = client.post("/aircraft/N1/inspections", json={**body, "location": "tailplane"})
    assert unknown.status_code == 422
    assert unknown.json()["column"] == "location"
    assert "tailplane" in unknown.json()["detail"]
    assert client.get("/aircraft/N1/inspections").json() == []
    stored = client.post("/aircraft/N1/inspections", json={**body, "location": "wing"})
    assert stored.status_code == 201, stored.text
    plain = {**body, "inspection_id": "D1"}
    assert client.post("/aircraft/N1/inspections", json=plain).status_code == 201
    # the same inspection re-sent is a duplicate; at another location, a conflict (not a
    # silent duplicate: it would be lost)
    assert client.post("/aircraft/N1/inspections", json=plain).status_code == 200
    moved = client.post("/aircraft/N1/inspections", json={**plain, "location": "wing"})
    assert moved.status_code == 409, moved.text
    assert "location_id" in moved.json()["detail"]
    listed = {
        i["inspection_id"]: i["location"] for i in client.get("/aircraft/N1/inspections").json()
    }
    assert listed == {"W1": "wing", "D1": "default"}
    assert client.get("/aircraft/N1/inspections/W1").json()["location"] == "wing"


def test_another_locations_inspection_leaves_the_default_forecast_as_it_was(
    client: TestClient,
) -> None:
    """The default location answers from its own inspections only: one at another location
    changes neither its model's evidence nor its forecast."""
    for tail, stress in (("LOW", 100.0), ("HIGH", 300.0)):
        add_tail(client, tail, 40, stress=stress)
    inspect(client, "LOW", START + timedelta(days=10), 0.00501)
    job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
    assert job["status"] == "succeeded", job["error"]
    before = client.get("/aircraft/HIGH/forecast", params={"horizon_days": 30}).json()
    client.put("/locations/wing", json=WING)
    elsewhere = {
        "inspection_id": "W1",
        "inspected_at": (START + timedelta(days=9)).isoformat(),
        "crack_length_m": 0.03,  # far from the default location's crack: never compared with it
        "location": "wing",
    }
    stored = client.post("/aircraft/HIGH/inspections", json=elsewhere)
    assert stored.status_code == 201, stored.text
    assert stored.json()["assessments"][0]["flagged"] is False
    after = client.get("/aircraft/HIGH/forecast", params={"horizon_days": 30}).json()
    # the same forecast; the wing, with no model until a retrain, is named as not assessed
    assert [note["location"] for note in after.pop("location_notes")] == ["wing"]
    assert after == {**before, "unassessed_locations": ["wing"]}


def _location(**values: object) -> StoredLocation:
    fields = {name: None for name in StoredLocation.__dataclass_fields__}
    return StoredLocation(**{**fields, "stress_factor": 1.0, **values})  # type: ignore[arg-type]


def test_a_locations_material_gives_its_law_and_its_own_constants_override_it() -> None:
    settings = Settings()
    law = physics(_location(material="7075-T6"), settings).law
    alloy = law_for("7075-T6")
    assert (law.c, law.m, law.gamma) == (alloy.c, alloy.m, alloy.gamma)
    assert law.critical_crack_m == settings.law().critical_crack_m
    own = _location(
        material="7075-T6", growth_law={"law": "paris", "paris_c": 2e-11, "paris_m": 3.1}
    )
    law = physics(own, settings).law
    assert (law.c, law.m, law.gamma) == (2e-11, 3.1, alloy.gamma)
    assert physics(_location(), settings).law == settings.law()


def test_a_locations_geometry_table_is_its_laws_with_f_at_a0_as_the_constant() -> None:
    table = {"crack_length_m": [0.002, 0.05], "factor": [1.1, 1.5]}
    law = physics(_location(geometry_table=table, initial_crack_m=0.014), Settings()).law
    assert law.geometry_table == GeometryTable((0.002, 0.05), (1.1, 1.5))
    assert law.geometry_factor == pytest.approx(1.2, rel=1e-12)  # F at a0 = 14 mm
    assert physics(_location(geometry_factor=1.3), Settings()).law.geometry_table is None


def test_local_stress_scales_the_recorded_loads_by_mission() -> None:
    flights = pd.DataFrame(
        {"stress_range_mpa": [100.0, 200.0, 50.0], "mission": ["M1", "M3", None]}
    )
    same = local_stress(flights, _location())
    assert same is flights  # the default location reads the recorded loads as they are
    scaled = local_stress(
        flights, _location(stress_factor=1.2, stress_factor_by_mission={"M3": 2.0})
    )
    np.testing.assert_array_equal(scaled["stress_range_mpa"], [120.0, 400.0, 60.0])
    np.testing.assert_array_equal(flights["stress_range_mpa"], [100.0, 200.0, 50.0])


def test_a_database_of_today_migrates_and_serves_the_same_answers(settings: Settings) -> None:
    """Rows stored before locations (the schema one revision back) become the default
    location's, the cached forecasts included, and answer as they did."""
    with serving(settings) as client:
        for tail, stress in (("LOW", 100.0), ("HIGH", 300.0)):
            add_tail(client, tail, 40, stress=stress)
        inspect(client, "LOW", START + timedelta(days=10), 0.00501)
        job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
        assert job["status"] == "succeeded", job["error"]
        forecast = client.get("/aircraft/HIGH/forecast").json()
        ranking = client.get("/fleet/ranking").json()
        inspections = client.get("/aircraft/LOW/inspections").json()
    migrate.downgrade(settings.database_url, BEFORE_LOCATIONS)
    engine = make_engine(settings.database_url)
    with engine.connect() as connection:
        stamps = connection.execute(text("SELECT aircraft_id, stamp FROM forecasts")).all()
        assert len(stamps) == 2
        assert "location_id" not in {
            c["name"] for c in inspect_db(connection).get_columns("inspections")
        }
    migrate.upgrade(settings.database_url)
    with engine.connect() as connection:
        kept = connection.execute(text("SELECT aircraft_id, stamp, location_id FROM forecasts"))
        assert sorted(kept) == sorted((i, s, DEFAULT_LOCATION_ID) for i, s in stamps)
    engine.dispose()
    with serving(settings) as client:
        assert client.get("/aircraft/HIGH/forecast").json() == forecast
        assert client.get("/fleet/ranking").json() == ranking
        assert client.get("/aircraft/LOW/inspections").json() == inspections


def test_a_non_detection_takes_its_locations_pod_curve(client: TestClient) -> None:
    """The catalogue's inspection method: a "nothing found" without a curve of its own takes
    the location's; one with its own keeps it; a location without a curve refuses it."""
    add_tail(client, "N1", 8)
    client.put("/locations/wing", json=WING)
    at = (START + timedelta(days=1)).isoformat()
    missed = {"inspected_at": at, "detected": False, "location": "wing"}
    assert (
        client.post("/aircraft/N1/inspections", json={**missed, "inspection_id": "M1"}).status_code
        == 201
    )
    own = {**missed, "inspection_id": "M2", "pod_a50_m": 0.001, "pod_a90_m": 0.002}
    assert client.post("/aircraft/N1/inspections", json=own).status_code == 201
    stored = {i["inspection_id"]: i for i in client.get("/aircraft/N1/inspections").json()}
    assert (stored["M1"]["pod_a50_m"], stored["M1"]["pod_a90_m"]) == (0.0015, 0.0025)
    assert (stored["M2"]["pod_a50_m"], stored["M2"]["pod_a90_m"]) == (0.001, 0.002)
    bare = {"inspected_at": at, "detected": False, "inspection_id": "M3"}  # default: no curve
    refused = client.post("/aircraft/N1/inspections", json=bare)
    assert refused.status_code == 422, refused.text
