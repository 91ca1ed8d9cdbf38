"""`fleetpinn predict` and the service give a never-inspected tail the same answer: the point
crack at the fleet's rate (its growth posterior is the fleet prior, whose median is about
exp(mu)), from the version's own model file (GET /models/{version}/file)."""

import math
from datetime import timedelta
from pathlib import Path

import pandas as pd
from fastapi.testclient import TestClient

from app.cli import main
from model.physics import ParisLaw, paris_closed_form
from tests.app.conftest import SQLITE_ONLY, START, add_tail, flights, retrained

pytestmark = SQLITE_ONLY

FLIGHTS = 400
# eight inspected tails growing 1.2 to 1.9 times the physics' crack: a fleet rate well above 1
INSPECTED = {f"N{k}": (150.0 + 10 * k, 1.2 + 0.1 * k) for k in range(8)}


def test_predict_without_inspections_marches_a_tail_at_the_fleets_rate_as_the_service(
    client: TestClient, tmp_path: Path
) -> None:
    law = ParisLaw()
    for tail, (stress, factor) in INSPECTED.items():
        add_tail(client, tail, FLIGHTS, stress=stress)
        for day in (50, 100):
            physics = float(paris_closed_form(law.initial_crack_m, stress, 4 * day, law))
            body = {
                "inspection_id": f"I{day}",
                "inspected_at": (START + timedelta(days=day)).isoformat(),
                "crack_length_m": law.initial_crack_m + factor * (physics - law.initial_crack_m),
            }
            assert client.post(f"/aircraft/{tail}/inspections", json=body).status_code == 201
    add_tail(client, "NEW", FLIGHTS, stress=190.0)  # never inspected
    version = retrained(client)["result"]["model_version"]
    service = client.get("/aircraft/NEW/forecast").json()
    fleet_rate = math.exp(
        client.get(f"/models/{version}").json()["metrics"]["tracking"]["growth_mean"]
    )
    assert fleet_rate > 1.2  # the case it is about: the fleet grows faster than the physics
    assert service["growth"]["inspection_ids"] == []
    assert abs(service["growth"]["factor_p50"] / fleet_rate - 1) < 0.01

    model = tmp_path / "model.pt"
    model.write_bytes(client.get(f"/models/{version}/file").content)
    rows = [{"tail": "NEW", **flight} for flight in flights(FLIGHTS, stress=190.0)]
    pd.DataFrame(rows).to_csv(tmp_path / "flights.csv", index=False)
    out = tmp_path / "predicted.csv"
    argv = ["predict", "--model", str(model), "--flights", str(tmp_path / "flights.csv")]
    assert main([*argv, "--out", str(out)]) == 0
    (predicted,) = pd.read_csv(out).to_dict("records")
    assert math.isclose(predicted["crack_length_m"], service["crack_length_m"], rel_tol=1e-9)
    at_one = float(paris_closed_form(law.initial_crack_m, 190.0, FLIGHTS, law))
    assert predicted["crack_length_m"] > at_one * 1.05  # not the physics at factor 1
