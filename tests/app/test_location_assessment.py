"""A new inspection is compared with its own location's forecast (app.services.forecasts.
assessment) in a fleet set up with its own locations and no `default`: each inspection gets the
crack its location's active version predicts for it, and one far from it is flagged."""

from datetime import timedelta
from typing import Any

from fastapi.testclient import TestClient

from tests.app.conftest import SQLITE_ONLY_SERVER, START

# the fleet of wing and keel, both trained on N1's and N2's inspections (no default location)
from tests.app.test_fleet_without_default import fleet, stored_database  # noqa: F401

pytestmark = SQLITE_ONLY_SERVER


def _inspection(name: str, crack_m: float) -> dict[str, Any]:
    return {
        "inspection_id": f"late-{name}",
        "inspected_at": (START + timedelta(days=8)).isoformat(),
        "crack_length_m": crack_m,
        "location": name,
    }


def test_each_locations_inspection_is_compared_with_that_locations_forecast(
    fleet: TestClient,  # noqa: F811
) -> None:
    client = fleet
    last = {
        name: client.get(f"/aircraft/N1/locations/{name}/forecast").json()["crack_length_m"]
        for name in ("wing", "keel")
    }
    body = [_inspection("wing", 0.0021), _inspection("keel", 0.02)]
    answer = client.post("/aircraft/N1/inspections", json=body)
    assert answer.status_code == 201, answer.text
    assessed = {a["inspection_id"]: a for a in answer.json()["assessments"]}
    wing, keel = assessed["late-wing"], assessed["late-keel"]
    # day 8 of N1's 10 days of flights: past the initial 2 mm, short of the last flight's crack
    assert 0.002 < wing["forecast_crack_m"] < last["wing"]
    assert 0.002 < keel["forecast_crack_m"] < last["keel"]
    assert wing["forecast_crack_m"] != keel["forecast_crack_m"]  # each its own stress and law
    assert abs(wing["forecast_z"]) < 3 and not wing["flagged"]
    assert keel["forecast_z"] > 3 and keel["flagged"]  # 20 mm where about 2 mm was expected
    listed = {i["inspection_id"]: i for i in client.get("/aircraft/N1/inspections").json()}
    assert listed["late-keel"]["flagged"] is True
    assert listed["late-keel"]["forecast_crack_m"] == keel["forecast_crack_m"]
