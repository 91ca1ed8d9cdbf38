"""Per-location models: a retrain is one job per location, each gated against its own
location's active version, and each location forecasts from its own local loads and physics."""

import math
import re
from datetime import timedelta
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import text

from app.db import make_engine
from app.local_server import wait_for_job
from tests.app.conftest import START, add_tail, inspect
from tests.app.snapshots import copied_for_each_test, served_settings

C, M = 1.5e-11, 3.8
WING = {"stress_factor": 1.5, "initial_crack_m": 0.002, "critical_crack_m": 0.04}


def _euler(crack: float, stress: float, flights: int) -> float:
    """The physics kernel's march: one Euler step of Paris' law per flight."""
    for _ in range(flights):
        crack += C * (stress * math.sqrt(math.pi * crack)) ** M
    return crack


def _retrain(client: TestClient) -> dict[str, dict[str, Any]]:
    accepted = client.post("/models/retrain")
    assert accepted.status_code == 202, accepted.text
    body = accepted.json()
    assert body["job_id"] == body["jobs"]["default"]
    done = {name: wait_for_job(client, job) for name, job in body["jobs"].items()}
    for name, job in done.items():
        assert job["status"] == "succeeded", (name, job["error"])
    return done


@pytest.fixture
def two_locations(client: TestClient) -> TestClient:
    """Two tails at constant stress, each location inspected on LOW."""
    _store_two_locations(client)
    return client


def _store_two_locations(client: TestClient) -> None:
    for tail, stress in (("LOW", 100.0), ("HIGH", 150.0)):
        add_tail(client, tail, 40, stress=stress)
    inspect(client, "LOW", START + timedelta(days=10), 0.00501)
    assert client.put("/locations/wing", json=WING).status_code == 201
    wing_inspection = {
        "inspection_id": "W1",
        "inspected_at": (START + timedelta(days=10)).isoformat(),
        "crack_length_m": _euler(0.002, 150.0, 40),
        "location": "wing",
    }
    assert client.post("/aircraft/LOW/inspections", json=wing_inspection).status_code == 201


def _store_trained(client: TestClient) -> None:
    """two_locations retrained (a job per location)."""
    _store_two_locations(client)
    _retrain(client)


stored_database, trained = copied_for_each_test("trained", _store_trained)


def test_a_retrain_is_one_job_per_location_and_each_forecasts_its_own_physics(
    two_locations: TestClient,
) -> None:
    client = two_locations
    jobs = _retrain(client)
    assert set(jobs) == {"default", "wing"}
    assert jobs["wing"]["params"]["location"] == "wing"
    assert "location" not in jobs["default"]["params"]  # today's retrain, as it was
    wing = client.get("/aircraft/HIGH/locations/wing/forecast", params={"horizon_days": 30})
    assert wing.status_code == 200, wing.text
    body = wing.json()
    # the wing sees 1.5 x the recorded 150 MPa from its own a0, and stops at its own a_crit
    assert body["crack_length_m"] == pytest.approx(_euler(0.002, 225.0, 40), rel=1e-12)
    assert body["critical_crack_m"] == 0.04
    default = client.get("/aircraft/HIGH/forecast", params={"horizon_days": 30}).json()
    assert default["crack_length_m"] == pytest.approx(_euler(0.005, 150.0, 40), rel=1e-12)
    named = client.get("/aircraft/HIGH/locations/default/forecast", params={"horizon_days": 30})
    summary = ("governing_location", "locations", "location", "location_notes")
    assert named.json() == {k: v for k, v in default.items() if k not in summary}
    assert wing.json()["model_version"] != default["model_version"]
    missing = client.get("/aircraft/HIGH/locations/nowhere/forecast")
    assert missing.status_code == 404


def test_the_promotion_gate_compares_each_location_with_its_own_active_version(
    two_locations: TestClient,
) -> None:
    client = two_locations
    first = _retrain(client)
    versions = {name: job["result"]["model_version"] for name, job in first.items()}
    active = {v["version"] for v in client.get("/models").json() if v["status"] == "active"}
    assert active == set(versions.values())  # one active version per location
    second = _retrain(client)
    for name, job in second.items():
        gate = job["result"]["metrics"]["gate"]
        assert gate["active_version"] == versions[name], name
        assert job["result"]["outcome"] == "activated", job["result"]["reason"]
    wing = client.get("/aircraft/HIGH/locations/wing/forecast").json()
    assert wing["model_version"] == second["wing"]["result"]["model_version"]


def test_new_flights_advance_each_location_at_its_own_stress(trained: TestClient) -> None:
    client = trained
    client.get("/aircraft/HIGH/locations/wing/forecast")  # its row is cached
    more = [
        {
            "flight_id": f"N{k}",
            "flown_at": (START + timedelta(days=11, hours=6 * k)).isoformat(),
            "stress_range_mpa": 150.0,
            "mission": "M1",
        }
        for k in range(4)
    ]
    assert client.post("/aircraft/HIGH/flights", json=more).status_code == 201
    wing = client.get("/aircraft/HIGH/locations/wing/forecast").json()
    assert wing["flights_flown"] == 44
    assert wing["crack_length_m"] == pytest.approx(_euler(0.002, 225.0, 44), rel=1e-12)


def test_the_aircraft_forecast_names_its_governing_location(trained: TestClient) -> None:
    client = trained
    body = client.get("/aircraft/HIGH/forecast").json()
    each = {
        name: client.get(f"/aircraft/HIGH/locations/{name}/forecast").json()
        for name in ("default", "wing")
    }
    # the body is the default location's full forecast, as before locations
    summary = ("governing_location", "locations", "location", "location_notes")
    assert {k: v for k, v in body.items() if k not in summary} == (each["default"])
    lines = {line["location"]: line for line in body["locations"]}
    assert set(lines) == {"default", "wing"}
    for name, full in each.items():
        assert lines[name]["prob_critical"] == full["prob_critical"]
        assert lines[name]["inspect_by"] == full["inspect_by"]
        assert lines[name]["model_version"] == full["model_version"]
    # the wing sees 1.5 x the stress from a smaller crack towards a smaller critical one
    assert each["wing"]["prob_critical"] > each["default"]["prob_critical"]
    assert body["governing_location"] == "wing"
    assert [line["location"] for line in body["locations"]] == ["wing", "default"]


def test_one_location_answers_without_a_summary(client: TestClient) -> None:
    add_tail(client, "LOW", 40, stress=100.0)
    inspect(client, "LOW", START + timedelta(days=10), 0.00501)
    _retrain(client)
    body = client.get("/aircraft/LOW/forecast").json()
    assert not {"governing_location", "locations", "unassessed_locations", "location"} & set(body)
    assert "location_notes" not in body


def test_the_ranking_and_the_export_list_tail_location_rows_grouped_by_aircraft(
    two_locations: TestClient,
) -> None:
    client = two_locations
    _retrain(client)
    ranking = client.get("/fleet/ranking", params={"limit": 10}).json()
    rows = [(item["tail"], item["location"]) for item in ranking["items"]]
    assert ranking["total"] == 4
    assert sorted(rows) == [
        ("HIGH", "default"),
        ("HIGH", "wing"),
        ("LOW", "default"),
        ("LOW", "wing"),
    ]
    tails = [tail for tail, _ in rows]
    assert tails[0] == tails[1] and tails[2] == tails[3]  # an aircraft's rows stay together
    for item in ranking["items"]:
        # each row is its location's own forecast, bit for bit (batch invariance)
        full = client.get(f"/aircraft/{item['tail']}/locations/{item['location']}/forecast").json()
        assert item["prob_critical"] == full["prob_critical"]
        assert item["crack_length_m"] == full["crack_length_m"]
        assert item["critical_crack_m"] == full["critical_crack_m"]
        assert item["model_version"] == full["model_version"]
    for first, second in (ranking["items"][0:2], ranking["items"][2:4]):
        # the governing row first: the higher P(critical)
        assert first["prob_critical"] >= second["prob_critical"]
        aircraft = client.get(f"/aircraft/{first['tail']}/forecast").json()
        assert aircraft["governing_location"] == first["location"]
    exported = client.get("/forecasts", params={"format": "json"}).json()
    assert [(row["tail"], row["location"]) for row in exported] == rows


def test_a_one_location_ranking_names_no_location(client: TestClient) -> None:
    add_tail(client, "LOW", 40, stress=100.0)
    inspect(client, "LOW", START + timedelta(days=10), 0.00501)
    _retrain(client)
    item = client.get("/fleet/ranking").json()["items"][0]
    assert "location" not in item and "model_version" not in item
    exported = client.get("/forecasts", params={"format": "json"}).json()
    assert "location" not in exported[0]


def test_the_batch_job_forecasts_every_location(trained: TestClient) -> None:
    client = trained
    job = wait_for_job(client, client.post("/forecasts/batch").json()["job_id"])
    assert job["status"] == "succeeded", job["error"]
    each = job["result"]["locations"]
    assert set(each) == {"default", "wing"}
    for name, part in each.items():
        assert part["forecasts"] == 2 and part["filled"] + part["kept"] == 2, name
    assert job["result"]["model_version"] == each["default"]["model_version"]


def test_a_replaced_entry_forecasts_from_its_new_loads(trained: TestClient) -> None:
    """Its cached rows were made under the entry replaced: they go, and the next forecast
    scales the loads as the entry now says (the model stays the one trained until a retrain)."""
    client = trained
    before = client.get("/aircraft/HIGH/locations/wing/forecast").json()
    assert client.put("/locations/wing", json={**WING, "stress_factor": 1.6}).status_code == 200
    after = client.get("/aircraft/HIGH/locations/wing/forecast").json()
    assert before["crack_length_m"] == pytest.approx(_euler(0.002, 225.0, 40), rel=1e-12)
    assert after["crack_length_m"] == pytest.approx(_euler(0.002, 240.0, 40), rel=1e-12)


def test_an_inspection_drops_only_its_own_locations_cached_rows(trained: TestClient) -> None:
    client = trained
    for name in ("default", "wing"):
        client.get(f"/aircraft/HIGH/locations/{name}/forecast")
    engine = make_engine(served_settings(client).database_url)

    def stamps() -> dict[int, int]:
        with engine.connect() as connection:
            query = text(
                "SELECT location_id, stamp FROM forecasts f JOIN aircraft a "
                "ON a.id = f.aircraft_id WHERE a.tail = 'HIGH'"
            )
            return {location: stamp for location, stamp in connection.execute(query)}

    before = stamps()
    assert len(before) == 2
    wing = {
        "inspection_id": "W2",
        "inspected_at": (START + timedelta(days=10)).isoformat(),
        "crack_length_m": _euler(0.002, 225.0, 40),
        "location": "wing",
    }
    assert client.post("/aircraft/HIGH/inspections", json=wing).status_code == 201
    after = stamps()
    engine.dispose()
    default_id = min(before)
    assert after == {default_id: before[default_id]}  # the default row kept, the wing's dropped


def test_the_tail_page_charts_each_location_with_its_own_inspections(
    trained: TestClient,
) -> None:
    client = trained
    page = client.get("/pages/aircraft/LOW")
    assert page.status_code == 200, page.text
    html = page.text
    assert html.count("<svg") == 2  # the default location's chart, then the wing's
    wing = html[html.index('id="location-wing"') :]
    assert "/aircraft/LOW/locations/wing/forecast" in wing
    default = html[: html.index('id="location-wing"')]
    # each chart marks its own location's inspection (LOW has one measured at each)

    def marks(chart: str) -> int:
        group = chart[chart.index('id="inspections-measured"') :]
        return group[: group.index("</g>")].count("<use")

    assert marks(default) == 1
    assert marks(wing) == 1


def test_the_fleet_page_lists_each_aircrafts_locations_together(
    trained: TestClient,
) -> None:
    client = trained
    html = client.get("/").text
    named = re.findall(
        r'/pages/aircraft/(\w+)[^<]*</a> <span class="location"[^>]*>([\w-]+)<', html
    )
    assert sorted(named) == [
        ("HIGH", "default"),
        ("HIGH", "wing"),
        ("LOW", "default"),
        ("LOW", "wing"),
    ]
    tails = [tail for tail, _ in named]
    assert tails[0] == tails[1] and tails[2] == tails[3]  # an aircraft's rows stay together
    ranked = client.get("/fleet/ranking").json()["items"]
    assert named == [(item["tail"], item["location"]) for item in ranked]


def test_an_aircraft_carries_a_listed_subset(two_locations: TestClient) -> None:
    """HIGH lists the default location only: no wing inspection, forecast or ranking row for
    it, while LOW keeps both; an empty list gives it every location back."""
    client = two_locations
    assert client.get("/aircraft/HIGH/locations").json()["locations"] == ["default", "wing"]
    bad = client.put("/aircraft/HIGH/locations", json={"locations": ["nowhere"]})
    assert bad.status_code == 422 and bad.json()["column"] == "locations"
    assert client.get("/aircraft/HIGH/locations").json()["locations"] == ["default", "wing"]
    only = client.put("/aircraft/HIGH/locations", json={"locations": ["default"]})
    assert only.status_code == 200 and only.json()["locations"] == ["default"]
    refused = client.post(
        "/aircraft/HIGH/inspections",
        json={
            "inspection_id": "W9",
            "inspected_at": (START + timedelta(days=10)).isoformat(),
            "crack_length_m": 0.003,
            "location": "wing",
        },
    )
    assert refused.status_code == 422 and refused.json()["column"] == "location"
    _retrain(client)
    assert client.get("/aircraft/HIGH/locations/wing/forecast").status_code == 404
    rows = [(i["tail"], i["location"]) for i in client.get("/fleet/ranking").json()["items"]]
    assert sorted(rows) == [("HIGH", "default"), ("LOW", "default"), ("LOW", "wing")]
    summary = client.get("/aircraft/HIGH/forecast").json()["locations"]
    assert [line["location"] for line in summary] == ["default"]
    assert client.put("/aircraft/HIGH/locations", json={"locations": []}).json()["locations"] == [
        "default",
        "wing",
    ]
    assert client.get("/aircraft/HIGH/locations/wing/forecast").status_code == 200


def test_a_location_not_yet_inspected_forecasts_from_its_catalogue_physics(
    two_locations: TestClient,
) -> None:
    """Its retrain stores the catalogue's analysis (the physics alone), so the aircraft's
    summary weighs it with the others; the bands carry the geometry factor's unknown trend
    from a0 on; its first inspection's retrain fits it, gated against the analysis."""
    client = two_locations
    keel = {"stress_factor": 1.6, "initial_crack_m": 0.002, "critical_crack_m": 0.03}
    assert client.put("/locations/keel", json=keel).status_code == 201
    jobs = _retrain(client)
    assert set(jobs) == {"default", "wing", "keel"}
    result = jobs["keel"]["result"]
    assert result["outcome"] == "activated", result["reason"]
    assert "no inspection at location 'keel'" in result["reason"]
    forecast = client.get("/aircraft/HIGH/locations/keel/forecast", params={"horizon_days": 30})
    assert forecast.status_code == 200, forecast.text
    body = forecast.json()
    assert body["model_version"] == result["model_version"]
    assert body["crack_length_m"] == pytest.approx(_euler(0.002, 240.0, 40), rel=1e-12)
    ahead = body["crack_at_horizon"]
    # no crack measured: the bands widen from the start (the physics alone, without the
    # settings' growth spread, would give none)
    assert ahead["p05"] < ahead["p50"] < ahead["p95"]
    lines = client.get("/aircraft/HIGH/forecast").json()["locations"]
    assert {line["location"] for line in lines} == {"default", "wing", "keel"}
    measured = {
        "inspection_id": "K1",
        "inspected_at": (START + timedelta(days=10)).isoformat(),
        "crack_length_m": _euler(0.002, 160.0, 40),
        "location": "keel",
    }
    assert client.post("/aircraft/LOW/inspections", json=measured).status_code == 201
    fitted = _retrain(client)["keel"]["result"]
    assert "analysis" not in fitted["metrics"]
    assert fitted["metrics"]["gate"]["active_version"] == result["model_version"]


def test_the_default_location_without_inspections_still_has_nothing_to_train_on(
    client: TestClient,
) -> None:
    add_tail(client, "LOW", 40, stress=100.0)
    accepted = client.post("/models/retrain").json()
    job = wait_for_job(client, accepted["job_id"])
    assert job["status"] == "failed"
    assert "no aircraft has both flights and a crack measurement" in job["error"]


def test_the_aircraft_answer_is_kept_until_one_of_its_locations_rows_changes(
    trained: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Kept under every location's row stamp (app.services.forecasts.forecast_answers): a repeat costs
    no forecast, and an inspection at one location (which drops its row) is never answered
    from before it."""
    from app.services.forecasts import forecast as forecast_service

    client = trained
    first = client.get("/aircraft/HIGH/forecast")
    assert first.status_code == 200, first.text
    calls = []
    real = forecast_service.forecast_tail
    monkeypatch.setattr(
        forecast_service, "forecast_tail", lambda *a, **k: calls.append(k) or real(*a, **k)
    )
    again = client.get("/aircraft/HIGH/forecast")
    assert again.content == first.content
    assert calls == []
    wing = {
        "inspection_id": "W9",
        "inspected_at": (START + timedelta(days=10)).isoformat(),
        "crack_length_m": _euler(0.002, 225.0, 40),
        "location": "wing",
    }
    assert client.post("/aircraft/HIGH/inspections", json=wing).status_code == 201
    after = client.get("/aircraft/HIGH/forecast")
    assert after.status_code == 200
    # made anew: the default location's forecast, and the wing's line from its new row
    assert [k.get("location") for k in calls] == [None]
    lines = {line["location"]: line for line in after.json()["locations"]}
    assert set(lines) == {"default", "wing"}
    full = client.get("/aircraft/HIGH/locations/wing/forecast").json()
    assert lines["wing"]["prob_critical"] == full["prob_critical"]
    assert lines["wing"]["inspect_by"] == full["inspect_by"]


# F rising towards an edge: 1.0 at a0 to 2.0 at a_crit, read at the current crack
EDGE_TABLE = {"crack_length_m": [0.002, 0.04], "factor": [1.0, 2.0]}


def _euler_table(crack: float, stress: float, flights: int) -> float:
    """_euler with F read from EDGE_TABLE at the crack of each flight (linear interpolation)."""
    (a0, a1), (f0, f1) = EDGE_TABLE["crack_length_m"], EDGE_TABLE["factor"]
    for _ in range(flights):
        factor = f0 + (f1 - f0) / (a1 - a0) * (min(max(crack, a0), a1) - a0)
        crack += C * (factor * stress * math.sqrt(math.pi * crack)) ** M
    return crack


def test_a_location_with_a_geometry_table_forecasts_with_f_at_the_current_crack(
    client: TestClient,
) -> None:
    """The catalogue's table reaches the fitted model, its stored file and the forecast: the
    crack now is the march with F(a), not with F held at its a0 value."""
    for tail, stress in (("LOW", 100.0), ("HIGH", 150.0)):
        add_tail(client, tail, 40, stress=stress)
    inspect(client, "LOW", START + timedelta(days=10), 0.00501)
    edge = {**WING, "geometry_table": EDGE_TABLE}
    assert client.put("/locations/edge", json=edge).status_code == 201
    measured = {
        "inspection_id": "E1",
        "inspected_at": (START + timedelta(days=10)).isoformat(),
        "crack_length_m": _euler_table(0.002, 150.0, 40),
        "location": "edge",
    }
    assert client.post("/aircraft/LOW/inspections", json=measured).status_code == 201
    _retrain(client)
    body = client.get("/aircraft/HIGH/locations/edge/forecast", params={"horizon_days": 30})
    assert body.status_code == 200, body.text
    crack = body.json()["crack_length_m"]
    assert crack == pytest.approx(_euler_table(0.002, 225.0, 40), rel=1e-12)
    flat = _euler(0.002, 225.0, 40)
    # F at the crack reached (2.03 mm) is 0.09 % above F(a0): 0.17 % more growth, 3e-5 of
    # the crack, far beyond the 1e-12 the march is matched to
    assert crack - flat > 1e-3 * (flat - 0.002)
