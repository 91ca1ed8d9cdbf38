"""A location whose inspections give a Paris exponent m <= 2 (a crack growing no faster than
the exponential law, where forecasts beyond the measured cracks are not defined,
model.posterior.UnforecastableLaw): its retrain is refused by the promotion gate with that
reason, nothing is stored, and the active version keeps answering."""

import math
from datetime import timedelta
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.cli import api, main
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


def test_a_learned_exponent_below_two_is_refused_with_why_and_the_active_version_kept(
    client: TestClient, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    assert client.put("/locations/lug", json=LEARNED).status_code == 201
    for k, stress in enumerate(STRESS):
        add_tail(client, f"N{k}", 400, stress=stress)
        carried = client.put(f"/aircraft/N{k}/locations", json={"locations": ["lug"]})
        assert carried.status_code == 200, carried.text
    first = _retrain(client)  # nothing inspected yet: the location's analysis
    assert first["status"] == "succeeded", first["error"]
    active = first["result"]["model_version"]
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
    assert job["outcome"] == "refused" and job["model_version"] is None
    gate = job["metrics"]["gate"]
    assert gate["passed"] is False and gate["active_version"] == active
    learned_m = job["metrics"]["paris"]["m"]
    assert 1.5 <= learned_m <= 2.0  # the calibration reads the fleet's m of 1.8
    assert f"m = {learned_m:.3g}" in job["outcome_reason"]
    assert f"v{active} stays active" in job["outcome_reason"]
    versions = client.get("/models").json()
    assert [v["version"] for v in versions] == [active]  # nothing stored
    assert versions[0]["status"] == "active"
    forecast = client.get("/aircraft/N3/locations/lug/forecast")
    assert forecast.status_code == 200 and forecast.json()["model_version"] == active

    page = client.get("/pages/models").text
    assert "no version stored" in page and f"m = {learned_m:.3g}" in page
    monkeypatch.setattr(
        api.Api, "call", lambda _self, method, path, **kw: client.request(method, path, **kw)
    )
    assert main(["client", "--url", "http://testserver", "jobs", job["job_id"]]) == 0
    printed = " ".join(capsys.readouterr().out.split())
    assert f"retrain REFUSED: no version is stored and v{active} stays active" in printed
