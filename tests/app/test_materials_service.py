"""The service with a user's materials file (FLEETPINN_MATERIALS_FILE): the NASGRO law retrains
and forecasts from its rows, and the per-location catalogue takes its alloys by name.  The
constants are tests.materials_values' TEST VALUES, not any real alloy's."""

from __future__ import annotations

from datetime import timedelta
from pathlib import Path

import pytest

from app.config import Settings
from app.local_server import wait_for_job
from model.materials import material
from tests.app.conftest import AS_OF, START, add_tail, inspect, serving
from tests.materials_values import TEST_A, TEST_B, nasgro_euler, write_materials

WING = {"stress_factor": 1.5, "initial_crack_m": 0.002, "critical_crack_m": 0.04}


def test_the_nasgro_law_retrains_and_forecasts_from_the_users_file(tmp_path: Path) -> None:
    ours = write_materials(tmp_path / "ours.csv", TEST_A, TEST_B)
    settings = Settings(
        database_url=f"sqlite:///{tmp_path / 'fleetpinn.db'}",
        kernel="physics",
        worker_poll_seconds=0.05,
        as_of=AS_OF,
        materials_file=ours,
        material="TEST-NASGRO-A",
        growth_law="nasgro",
    )
    alloy, wing_alloy = material("TEST-NASGRO-A", ours), material("TEST-NASGRO-B", ours)
    with serving(settings) as client:
        for tail, stress in (("LOW", 100.0), ("HIGH", 150.0)):
            add_tail(client, tail, 40, stress=stress)
        at = START + timedelta(days=10)
        inspect(client, "LOW", at, nasgro_euler(alloy, [100.0] * 40, 0.005))
        # the catalogue takes the file's alloys by name, and refuses one it lacks
        refused = client.put("/locations/wing", json={**WING, "material": "TEST-NASGRO-C"})
        assert refused.status_code == 422, refused.text
        assert refused.json()["detail"][0]["loc"] == ["body", "material"]
        assert "unknown material 'TEST-NASGRO-C'" in refused.json()["reason"]
        stored = client.put("/locations/wing", json={**WING, "material": "TEST-NASGRO-B"})
        assert stored.status_code == 201, stored.text
        assert client.get("/locations/wing").json()["material"] == "TEST-NASGRO-B"
        wing_inspection = {
            "inspection_id": "W1",
            "inspected_at": at.isoformat(),
            "crack_length_m": nasgro_euler(wing_alloy, [150.0] * 40, 0.002),
            "location": "wing",
        }
        assert client.post("/aircraft/LOW/inspections", json=wing_inspection).status_code == 201
        accepted = client.post("/models/retrain")
        assert accepted.status_code == 202, accepted.text
        for name, job in accepted.json()["jobs"].items():
            done = wait_for_job(client, job)
            assert done["status"] == "succeeded", (name, done["error"])
        default = client.get("/aircraft/HIGH/forecast", params={"horizon_days": 30}).json()
        expected = nasgro_euler(alloy, [150.0] * 40, 0.005)
        assert default["crack_length_m"] == pytest.approx(expected, rel=1e-9)
        wing = client.get("/aircraft/HIGH/locations/wing/forecast", params={"horizon_days": 30})
        assert wing.status_code == 200, wing.text
        expected = nasgro_euler(wing_alloy, [225.0] * 40, 0.002)
        assert wing.json()["crack_length_m"] == pytest.approx(expected, rel=1e-9)
        versions = client.get("/models").json()
        assert len(versions) == 2  # the default location's and the wing's
        assert {v["metrics"]["growth_law"]["name"] for v in versions} == {"nasgro"}
