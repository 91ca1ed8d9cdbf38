"""A location whose inspections give a Paris exponent m < 2 (a crack growing no faster than the
exponential law): the shape's map beyond the measured cracks integrates the damage on a grid
(model.extrapolation), so such a law is forecast like any other, and its version is judged by
the promotion gate as any other is."""

import math
from datetime import timedelta
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.local_server import wait_for_job
from tests.app.conftest import SQLITE_ONLY, START, add_tail

pytestmark = SQLITE_ONLY

LEARNED = {
    "initial_crack_m": 0.002,
    "critical_crack_m": 0.05,
    "growth_law": {"law": "paris", "learn": True},
}
STRESS = (80.0, 100.0, 130.0, 160.0)


def _paris_crack(stress_mpa: float, flights: int, m: float = 1.8, c: float = 6e-8) -> float:
    """Paris' closed form from 2 mm at F = 1: a**p = a0**p + p C (dS sqrt(pi))**m N, p = 1 - m/2."""
    p = 1 - m / 2
    return (0.002**p + p * c * (stress_mpa * math.sqrt(math.pi)) ** m * flights) ** (1 / p)


def _retrain(client: TestClient) -> dict[str, Any]:
    accepted = client.post("/models/retrain")
    assert accepted.status_code == 202, accepted.text
    (job,) = accepted.json()["jobs"].values()
    return wait_for_job(client, job)


def test_a_learned_exponent_below_two_is_forecast_like_any_other(client: TestClient) -> None:
    assert client.put("/locations/lug", json=LEARNED).status_code == 201
    for k, stress in enumerate(STRESS):
        add_tail(client, f"N{k}", 400, stress=stress)
        carried = client.put(f"/aircraft/N{k}/locations", json={"locations": ["lug"]})
        assert carried.status_code == 200, carried.text
    first = _retrain(client)  # nothing inspected yet: the location's analysis
    assert first["status"] == "succeeded", first["error"]
    for k, stress in enumerate(STRESS):  # four inspections a tail of a crack growing at m = 1.8
        for day in (25, 50, 75, 100):
            body = {
                "inspection_id": f"I{day}",
                "inspected_at": (START + timedelta(days=day)).isoformat(),
                "crack_length_m": _paris_crack(stress, 4 * day),
                "location": "lug",
            }
            answer = client.post(f"/aircraft/N{k}/inspections", json=body)
            assert answer.status_code == 201, answer.text

    job = _retrain(client)
    assert job["status"] == "succeeded" and job["error"] is None, job["error"]
    learned_m = job["metrics"]["paris"]["m"]
    assert 1.5 <= learned_m <= 2.0  # the calibration reads the fleet's m of 1.8
    assert job["outcome"] == "activated", job["outcome_reason"]
    forecast = client.get("/aircraft/N3/locations/lug/forecast")
    assert forecast.status_code == 200, forecast.text
    body = forecast.json()
    assert body["model_version"] == job["result"]["model_version"]
    # the last inspection was at the last flight: the crack there is the measured one
    assert body["crack_length_m"] == pytest.approx(_paris_crack(STRESS[3], 400), rel=0.05)
