"""Probabilistic forecasts, the ranking's orders, non-detections in training, repairs."""

import math
from collections.abc import Iterator
from datetime import timedelta
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from tests.app.conftest import (
    SQLITE_ONLY,
    START,
    add_tail,
    forget_kept_answers,
    inspect,
    retrained,
    serving,
    settings_in,
)

C, M = 1.5e-11, 3.8


def _euler(crack: float, stress: float, flights: int) -> float:
    for _ in range(flights):
        crack += C * (stress * math.sqrt(math.pi * crack)) ** M
    return crack


def _retrain(client: TestClient, **params: Any) -> int:
    version: int = retrained(client, **params)["model_version"]
    return version


def _length(value: float | None) -> float:
    """A reported crack quantile; null: at or past a_crit (app.services.forecasts.tail_status), beyond
    every length."""
    return float("inf") if value is None else value


def _ordered(band: dict[str, Any]) -> bool:
    return bool(_length(band["p05"]) <= _length(band["p50"]) <= _length(band["p95"]))


@pytest.fixture(scope="module")
def mixed_service(
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[tuple[TestClient, Settings]]:
    """Three tails flying a mix of missions (usage spread), 4 a day for 60 days; NEAR starts
    close to the critical crack.  Shared by the module's read-only tests: a test that changes
    the settings does so through monkeypatch."""
    settings = settings_in(tmp_path_factory.mktemp("mixed"))
    with serving(settings) as client:
        for tail, crack in (("NEAR", 0.03), ("MILD", None), ("MID", 0.012)):
            add_tail(client, tail, 240, stress=[90.0, 140.0, 100.0, 200.0, 95.0, 120.0])
            answer = client.put(f"/aircraft/{tail}", json={"initial_crack_m": crack})
            assert answer.status_code == 200
        inspect(client, "MILD", START + timedelta(days=30), 0.00502)
        _retrain(client)
        yield client, settings


@pytest.fixture
def mixed(mixed_service: tuple[TestClient, Settings]) -> TestClient:
    return mixed_service[0]


def test_forecast_bands_are_ordered_and_risk_is_a_probability(mixed: TestClient) -> None:
    near = mixed.get("/aircraft/NEAR/forecast", params={"horizon_days": 365}).json()
    mild = mixed.get("/aircraft/MILD/forecast", params={"horizon_days": 365}).json()
    for body in (near, mild):
        assert body["samples"] == 200
        assert body["model_uncertainty"] is False  # physics kernel: nothing to be unsure of
        assert 0.0 <= body["prob_critical"] <= 1.0
        assert _ordered(body["crack_length_band"])
        assert all(_ordered(p) for p in body["trajectory"])
    assert near["prob_critical"] > mild["prob_critical"]
    assert mild["prob_critical"] == 0.0
    assert mild["inspect_by"] is None
    assert mild["flights_to_critical_quantiles"] == {"p05": None, "p50": None, "p95": None}
    # usage spread widens the band as it goes
    far = near["trajectory"][len(near["trajectory"]) // 2]
    assert far["p05"] < _length(far["p95"])
    quantiles = near["flights_to_critical_quantiles"]
    assert quantiles["p05"] <= quantiles["p50"] <= quantiles["p95"]
    assert near["critical_date_quantiles"]["p05"] <= near["critical_date_quantiles"]["p95"]
    # inspect by half the p05 time to critical
    origin = near["origin"]
    days_to_p05 = quantiles["p05"] / near["flights_per_day"]
    inspect_days = (_parse(near["inspect_by"]) - _parse(origin)) / timedelta(days=1)
    assert inspect_days == pytest.approx(days_to_p05 / 2, abs=1 / near["flights_per_day"])
    # cached per horizon: the same answer again
    again = mixed.get("/aircraft/NEAR/forecast", params={"horizon_days": 365}).json()
    assert again["prob_critical"] == near["prob_critical"]


def _parse(value: str) -> Any:
    from datetime import datetime

    return datetime.fromisoformat(value)


def test_planned_utilization_drives_the_forecast(mixed: TestClient) -> None:
    light = {"flights_per_day": 2, "missions": [{"stress_range_mpa": 90.0, "share": 1}]}
    heavy = {
        "flights_per_day": 6,
        "missions": [
            {"stress_range_mpa": 200.0, "share": 3},
            {"stress_range_mpa": 250.0, "share": 1},
        ],
    }
    answers = [
        mixed.post("/aircraft/MID/forecast", json={"horizon_days": 730, "planned": plan}).json()
        for plan in (light, heavy)
    ]
    assert [a["planned"] for a in answers] == [True, True]
    assert answers[0]["flights_per_day"] == 2
    assert answers[1]["prob_critical"] > answers[0]["prob_critical"]
    assert _length(answers[1]["trajectory"][-1]["p50"]) > answers[0]["trajectory"][-1]["p50"]
    assert all(_ordered(p) for a in answers for p in a["trajectory"])


@pytest.mark.parametrize(
    ("planned", "field"),
    [
        (
            {"flights_per_day": 0, "missions": [{"stress_range_mpa": 90, "share": 1}]},
            "flights_per_day",
        ),
        ({"flights_per_day": 2, "missions": []}, "missions"),
        ({"flights_per_day": 2, "missions": [{"stress_range_mpa": 90, "share": -1}]}, "share"),
        ({"flights_per_day": 2, "missions": [{"stress_range_mpa": 90, "share": 0}]}, "missions"),
        (
            {"flights_per_day": 2, "missions": [{"stress_range_mpa": 0, "share": 1}]},
            "stress_range_mpa",
        ),
    ],
)
def test_bad_plans_are_422_naming_the_field(
    client: TestClient, planned: dict[str, Any], field: str
) -> None:
    answer = client.post("/aircraft/ANY/forecast", json={"planned": planned})
    assert answer.status_code == 422
    assert field in answer.json()["detail"][0]["loc"]


def test_ranking_orders_by_risk_crack_and_due(mixed: TestClient) -> None:
    by_risk = mixed.get("/fleet/ranking", params={"horizon_days": 365}).json()
    assert (by_risk["by"], by_risk["horizon_days"], by_risk["total"]) == ("risk", 365, 3)
    assert [i["tail"] for i in by_risk["items"]] == ["NEAR", "MID", "MILD"]
    top = by_risk["items"][0]
    assert top["prob_critical"] > 0 and _ordered(top["crack_length_band"])
    assert top["inspect_by"] is not None and top["last_inspection"] is None
    mild = by_risk["items"][2]
    assert mild["last_inspection"]["crack_length_m"] == 0.00502
    assert mild["last_inspection"]["detected"] is True
    single = mixed.get("/aircraft/NEAR/forecast", params={"horizon_days": 365}).json()
    assert top["prob_critical"] == single["prob_critical"]  # the same samples
    assert top["flights_to_critical_quantiles"] == single["flights_to_critical_quantiles"]

    by_crack = mixed.get("/fleet/ranking", params={"by": "crack", "limit": 2}).json()
    assert [i["tail"] for i in by_crack["items"]] == ["NEAR", "MID"]
    by_due = mixed.get("/fleet/ranking", params={"by": "due", "horizon_days": 3650}).json()
    due = [i["inspect_by"] for i in by_due["items"]]
    known = [d for d in due if d is not None]
    assert known == sorted(known) and len(known) >= 2
    assert due[: len(known)] == known  # none due last

    unknown = mixed.get("/fleet/ranking", params={"by": "soonest"})
    assert unknown.status_code == 422
    assert unknown.json()["detail"][0]["loc"] == ["query", "by"]


@SQLITE_ONLY  # the forecasts' arithmetic, above the storage
def test_repair_restarts_the_forecast_crack(client: TestClient) -> None:
    add_tail(client, "R1", 80, stress=200.0)
    inspect(client, "R1", START + timedelta(days=5), 0.0052)
    _retrain(client)
    before = client.get("/aircraft/R1/forecast").json()
    # its own inspection (0.0052 m, a little over the physics) moves its factor a little
    assert before["crack_length_m"] == pytest.approx(_euler(0.005, 200.0, 80), rel=1e-5)
    repair = {
        "inspection_id": "REP",
        "inspected_at": (START + timedelta(days=10)).isoformat(),  # after 40 flights
        "crack_length_m": 0.006,
        "repaired": True,
        "crack_after_repair_m": 0.001,
    }
    assert client.post("/aircraft/R1/inspections", json=repair).status_code == 201
    after = client.get("/aircraft/R1/forecast").json()
    assert after["flights_flown"] == 80
    assert after["crack_length_m"] == pytest.approx(_euler(0.001, 200.0, 40), rel=5e-5)
    assert after["crack_length_band"]["p50"] == pytest.approx(after["crack_length_m"], rel=1e-5)
    ranked = client.get("/fleet/ranking").json()["items"][0]
    assert ranked["crack_length_m"] == after["crack_length_m"]
    assert ranked["last_inspection"]["repaired"] is True
    # a retrain still works with the restarted segment (its inspection is its initial crack)
    _retrain(client)


@SQLITE_ONLY  # the forecasts' arithmetic, above the storage
def test_non_detection_pushes_the_trained_model_below_the_threshold(
    client: TestClient, settings: Any
) -> None:
    """A residual model trained on measured tails, then with a non-detection at a crack the first
    model predicts above the threshold: the retrained prediction moves below it."""
    settings.posterior_restarts = 2  # a two-mode mixture: each further mode is one more fit
    for tail, stress in (("A", 150.0), ("B", 250.0), ("C", 200.0)):
        add_tail(client, tail, 400, stress=stress)
    end = START + timedelta(days=100)
    inspect(client, "A", end, _euler(0.005, 150.0, 400))
    inspect(client, "B", end, _euler(0.005, 250.0, 400))
    params = {"kernel": "residual", "lbfgs_iterations": 30, "holdout_fraction": 0}
    _retrain(client, **params)
    first = client.get("/aircraft/C/forecast").json()
    threshold = 0.005 + 0.5 * (first["crack_length_m"] - 0.005)
    assert first["crack_length_m"] > threshold
    assert first["model_uncertainty"] is True
    miss = {
        "inspection_id": "NONE",
        "inspected_at": end.isoformat(),
        "detected": False,
        "detection_threshold_m": threshold,
    }
    assert client.post("/aircraft/C/inspections", json=miss).status_code == 201
    version = _retrain(client, **params)
    # The gate scores measured cracks only: bending below the threshold costs A and B a little
    # accuracy, so the candidate is refused until an admin decides the evidence wins.
    gate = client.get(f"/models/{version}").json()["gate"]
    assert not gate["passed"] and gate["evaluated_on"] == "training"
    assert client.post(f"/models/{version}/activate").json()["status"] == "active"
    second = client.get("/aircraft/C/forecast").json()
    assert second["model_version"] == version
    assert second["crack_length_m"] < first["crack_length_m"]
    assert second["crack_length_m"] < threshold * 1.02
    model = client.get(f"/models/{version}").json()
    assert model["training"]["non_detections"] == 1
    assert model["training"]["posterior"]["kind"] == "laplace"
    assert model["training"]["posterior"]["modes"] == 2


def test_another_sample_count_refills_the_cache(
    mixed_service: tuple[TestClient, Settings], monkeypatch: pytest.MonkeyPatch
) -> None:
    mixed, settings = mixed_service
    monkeypatch.setattr(settings, "forecast_samples", 50)
    # changed in place under the running app, the settings are the very object the answers
    # were kept under (a process's settings never change: app.config), so nothing kept counts
    forget_kept_answers()
    assert mixed.get("/aircraft/NEAR/forecast").json()["samples"] == 50
    ranked = mixed.get("/fleet/ranking").json()
    assert ranked["total"] == 3 and ranked["items"][0]["tail"] == "NEAR"
