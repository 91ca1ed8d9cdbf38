"""Records that can be put right: plausibility bounds (422, nothing stored), corrections and
deletions (audited, forecasts recomputed), and inspections far from the forecast flagged."""

from __future__ import annotations

import math
from datetime import UTC, datetime, timedelta

import pandas as pd
import pytest
from fastapi.testclient import TestClient

from app.local_server import wait_for_job
from tests.app.conftest import START, add_tail, flights, inspect
from tests.app.snapshots import copied_for_each_test

C, M = 1.5e-11, 3.8


def _euler(crack: float, stress: float, count: int) -> float:
    for _ in range(count):
        crack += C * (stress * math.sqrt(math.pi * crack)) ** M
    return crack


def _store_fleet(client: TestClient) -> None:
    """Two tails of 40 flights at constant stress and the physics model active (exact Paris)."""
    add_tail(client, "LOW", 40, stress=100.0)
    add_tail(client, "MID", 40, stress=150.0)
    inspect(client, "LOW", START + timedelta(days=10), _euler(0.005, 100.0, 40))
    job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
    assert job["status"] == "succeeded", job["error"]


stored_database, fleet = copied_for_each_test("fleet", _store_fleet)


def _inspection(inspection_id: str, **fields: object) -> dict[str, object]:
    at = (START + timedelta(days=10, hours=1)).isoformat()
    return {"inspection_id": inspection_id, "inspected_at": at, **fields}


@pytest.mark.parametrize(
    ("body", "column", "reason"),
    [
        ({"crack_length_m": 5.0}, "crack_length_m", "must be <= 0.5 m"),
        (
            {"inspected_at": "2031-01-01T00:00:00Z", "crack_length_m": 0.006},
            "inspected_at",
            "lies in the future",
        ),
        (
            {"crack_length_m": 0.04, "repaired": True, "crack_after_repair_m": 0.05},
            "crack_after_repair_m",
            "must be < the critical crack",
        ),
        (
            {"detected": False, "detection_threshold_m": 2.0},
            "detection_threshold_m",
            "must be <= 0.5 m",
        ),
    ],
)
def test_implausible_inspections_are_422_and_store_nothing(
    client: TestClient, body: dict[str, object], column: str, reason: str
) -> None:
    add_tail(client, "N1", 4)
    good = _inspection("OK", crack_length_m=0.005)
    answer = client.post("/aircraft/N1/inspections", json=[good, _inspection("BAD") | body])
    assert answer.status_code == 422, answer.text
    assert (answer.json()["row"], answer.json()["column"]) == (2, column)
    assert reason in answer.json()["reason"]
    assert client.get("/aircraft/N1/inspections").json() == []


def test_implausible_flights_and_initial_crack_are_422(client: TestClient) -> None:
    ahead = (datetime.now(UTC) + timedelta(days=2)).isoformat()
    assert client.put("/aircraft/N1").status_code == 201
    cases = [
        ([{"flight_id": "F", "flown_at": ahead, "stress_range_mpa": 100.0}], "flown_at"),
        ([{"flight_id": "F", "flown_at": START.isoformat(), "stress_range_mpa": 5e3}], "stress"),
    ]
    for body, column in cases:
        answer = client.post("/aircraft/N1/flights", json=body)
        assert answer.status_code == 422 and answer.json()["column"].startswith(column)
    rows = pd.DataFrame([{"tail": "N2", **f} for f in flights(3)])
    rows.loc[2, "flown_at"] = ahead
    upload = client.post("/flights/upload", files={"file": ("f.csv", rows.to_csv(index=False))})
    assert (upload.status_code, upload.json()["row"]) == (422, 3)
    assert client.get("/aircraft/N2").status_code == 404  # not even the tail was created
    initial = client.put("/aircraft/N1", json={"initial_crack_m": 0.5})
    assert initial.status_code == 422
    assert initial.json()["column"] == "initial_crack_m"
    assert "critical crack (0.05 m)" in initial.json()["reason"]
    assert client.get("/aircraft/N1").json()["initial_crack_m"] is None


def test_inspections_are_compared_with_the_forecast(fleet: TestClient) -> None:
    truth = _euler(0.005, 150.0, 40)
    near = fleet.post("/aircraft/MID/inspections", json=_inspection("NEAR", crack_length_m=truth))
    assert near.status_code == 201
    [assessed] = near.json()["assessments"]
    assert assessed["forecast_crack_m"] == pytest.approx(truth, rel=1e-12)
    assert assessed["forecast_z"] == pytest.approx(0.0, abs=1e-9)
    assert not assessed["flagged"]
    # 3x the forecast (a slip of units or tails): stored, but flagged.  The physics model has no
    # weight posterior and the fleet no growth scatter, so only the sizing error spreads it.
    far = fleet.post("/aircraft/MID/inspections", json=_inspection("FAR", crack_length_m=3 * truth))
    [flag] = far.json()["assessments"]
    sizing_sd = math.hypot(0.05, 1e-4 / truth)
    # (and the geometry factor's trend past the one crack measured, 0.00501 m, barely)
    assert flag["forecast_z"] == pytest.approx(math.log(3) / sizing_sd, rel=1e-5)
    assert flag["flagged"] and far.status_code == 201
    nothing = [
        _inspection("MISS", detected=False, detection_threshold_m=0.002),  # would have found it
        _inspection("BELOW", detected=False, detection_threshold_m=0.02),
    ]
    answer = fleet.post("/aircraft/MID/inspections", json=nothing).json()["assessments"]
    assert [a["flagged"] for a in answer] == [True, False]
    listed = {
        i["inspection_id"]: i["flagged"] for i in fleet.get("/aircraft/MID/inspections").json()
    }
    assert listed == {"NEAR": False, "FAR": True, "MISS": True, "BELOW": False}
    ranked = {i["tail"]: i for i in fleet.get("/fleet/ranking").json()["items"]}
    assert ranked["MID"]["flagged_inspection_ids"] == ["FAR", "MISS"]
    assert ranked["LOW"]["flagged_inspection_ids"] == []
    assert "far from the forecast" in fleet.get("/pages/aircraft/MID").text


def test_correcting_an_inspection_rechecks_it_and_audits_the_old_values(fleet: TestClient) -> None:
    truth = _euler(0.005, 150.0, 40)
    fleet.post("/aircraft/MID/inspections", json=_inspection("I1", crack_length_m=10 * truth))
    fixed = fleet.patch("/aircraft/MID/inspections/I1", json={"crack_length_m": truth})
    assert fixed.status_code == 200, fixed.text
    assert (fixed.json()["crack_length_m"], fixed.json()["flagged"]) == (truth, False)
    assert fleet.get("/fleet/ranking").json()["items"][0]["flagged_inspection_ids"] == []
    event = fleet.get("/audit", params={"subject": "MID/I1"}).json()["items"][0]
    assert event["action"] == "inspection.correct" and event["actor"] == "test-admin"
    assert event["detail"]["before"]["crack_length_m"] == 10 * truth
    assert event["detail"]["changes"] == ["crack_length_m"]
    # A correction is checked as a new record is: nothing changes when it is wrong.
    for change in ({"detected": False}, {"crack_length_m": 7.0}, {"inspection_id": "X"}):
        assert fleet.patch("/aircraft/MID/inspections/I1", json=change).status_code == 422
    assert fleet.get("/aircraft/MID/inspections/I1").json()["crack_length_m"] == truth
    to_nothing = {"detected": False, "crack_length_m": None, "detection_threshold_m": 0.02}
    assert fleet.patch("/aircraft/MID/inspections/I1", json=to_nothing).json()["detected"] is False
    gone = fleet.delete("/aircraft/MID/inspections/I1")
    assert gone.status_code == 200 and gone.json()["detection_threshold_m"] == 0.02
    assert fleet.get("/aircraft/MID/inspections/I1").status_code == 404
    assert fleet.delete("/aircraft/MID/inspections/I1").status_code == 404
    deleted = fleet.get("/audit", params={"action": "inspection.delete"}).json()["items"][0]
    assert deleted["detail"]["before"]["detection_threshold_m"] == 0.02


def test_correcting_and_deleting_flights_recomputes_the_forecast(fleet: TestClient) -> None:
    assert fleet.get("/aircraft/MID/forecast").json()["crack_length_m"] == pytest.approx(
        _euler(0.005, 150.0, 40), rel=1e-12
    )
    fixed = fleet.patch("/aircraft/MID/flights/F0040", json={"stress_range_mpa": 300.0})
    assert fixed.status_code == 200 and fixed.json()["stress_range_mpa"] == 300.0
    corrected = fleet.get("/aircraft/MID/forecast").json()
    assert corrected["crack_length_m"] == pytest.approx(
        _euler(_euler(0.005, 150.0, 39), 300.0, 1), rel=1e-12
    )
    assert fleet.delete("/aircraft/MID/flights/F0040").json()["stress_range_mpa"] == 300.0
    after = fleet.get("/aircraft/MID/forecast").json()
    assert after["flights_flown"] == 39
    assert after["crack_length_m"] == pytest.approx(_euler(0.005, 150.0, 39), rel=1e-12)
    assert fleet.get("/aircraft/MID/flights/F0040").status_code == 404
    assert (
        fleet.patch("/aircraft/MID/flights/F0001", json={"stress_range_mpa": -1}).status_code == 422
    )
    assert fleet.patch("/aircraft/GHOST/flights/F0001", json={"mission": "M2"}).status_code == 404
    actions = [e["action"] for e in fleet.get("/audit").json()["items"][:2]]
    assert actions == ["flight.delete", "flight.correct"]
