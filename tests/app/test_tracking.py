"""Individual aircraft tracking through the service: each tail's forecast honours its own
inspections, uninspected tails get the fleet prior, an inspection moves only its own tail."""

import math
import time
from datetime import timedelta

import numpy as np
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select

from app.config import Settings
from app.db import make_engine, make_session_factory
from app.local_server import wait_for_job
from app.tables import Aircraft, Forecast
from tests.app.conftest import START, add_tail, inspect
from tests.app.snapshots import copied_for_each_test, served_settings

C, M, A0 = 1.5e-11, 3.8, 0.005
STRESS, FLIGHTS = 250.0, 300
FACTORS = (0.7, 0.8, 0.9, 1.0, 1.1, 1.25, 1.4, 1.6)  # each tail's own growth rate


def _euler(factor: float, flights: int = FLIGHTS) -> float:
    crack = A0
    for _ in range(flights):
        crack += factor * C * (STRESS * math.sqrt(math.pi * crack)) ** M
    return crack


LAST_FLIGHT = START + timedelta(hours=6 * (FLIGHTS - 1), minutes=30)


def _store_tracked(client: TestClient) -> None:
    """Eight tails at one stress that grow at their own rates, each inspected once; one more
    tail never inspected."""
    for i, factor in enumerate(FACTORS):
        add_tail(client, f"T{i}", FLIGHTS, stress=STRESS)
        inspect(client, f"T{i}", LAST_FLIGHT, _euler(factor))
    add_tail(client, "NEW", FLIGHTS, stress=STRESS)
    job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
    assert job["status"] == "succeeded", job["error"]


stored_database, tracked = copied_for_each_test("tracked", _store_tracked)


@pytest.fixture
def settings(tracked: TestClient) -> Settings:
    """The settings the copy is served with."""
    return served_settings(tracked)


def _forecast(client: TestClient, tail: str) -> dict:
    answer = client.get(f"/aircraft/{tail}/forecast", params={"horizon_days": 30})
    assert answer.status_code == 200, answer.text
    return answer.json()


def test_each_tail_follows_its_own_inspections(tracked: TestClient) -> None:
    fast = _forecast(tracked, "T7")
    growth = fast["growth"]
    assert growth["fleet_growth_sd"] > 0.1  # learned from the eight tails' spread
    assert growth["inspection_ids"] == [f"I-{LAST_FLIGHT:%Y%m%d%H%M}"]
    # factors are against the fitted model's rate: T7's against the fleet's (the tail never
    # inspected) is its own against the eight's geometric mean
    fleet = _forecast(tracked, "NEW")["growth"]["factor_p50"]
    own = FACTORS[7] / math.exp(sum(math.log(f) for f in FACTORS) / len(FACTORS))
    assert growth["factor_p05"] / fleet < own < growth["factor_p95"] / fleet
    assert growth["factor_p50"] / fleet > 1.2
    measured, shared = _euler(FACTORS[7]), _euler(1.0)
    # between the fleet model's estimate and the measurement, close to the measurement
    assert shared < fast["crack_length_m"] <= measured * 1.01
    assert abs(fast["crack_length_m"] / measured - 1) < 0.03
    band = fast["crack_length_band"]
    assert band["p05"] <= measured <= band["p95"]


@pytest.mark.xfail(
    strict=True,
    reason="issue 39, open: eight tails inspected once at one time; the geometry shape's "
    "posterior mean carried inside the march is not the law's, so a tail never inspected reads "
    "1.9 % above the crack at the fleet's rate (the test's 1 % assumes the law's shape)",
)
def test_an_uninspected_tail_gets_the_fleet_prior(tracked: TestClient) -> None:
    new = _forecast(tracked, "NEW")
    growth = new["growth"]
    assert growth["inspection_ids"] == []
    assert growth["factor_p05"] < 0.85 and growth["factor_p95"] > 1.15
    # the fleet's own rate: these eight grow ~1.06x the law's on average (the geometric mean
    # of FACTORS), and a tail never inspected inherits it: its crack is the one at that rate
    fleet_rate = math.exp(sum(math.log(f) for f in FACTORS) / len(FACTORS))
    assert new["crack_length_m"] == pytest.approx(_euler(fleet_rate), rel=0.01)
    band = new["crack_length_band"]
    # honest: the spread of the inspected tails' cracks lies within its band, whose p95 may lie
    # past a_crit (null): eight inspected tails bound the fleet's spread loosely, and a tail
    # never inspected is drawn with its upper confidence limit (model.tracking)
    assert band["p05"] < _euler(0.8)
    assert band["p95"] is None or band["p95"] > _euler(1.25)
    assert growth["factor_p95"] / growth["factor_p50"] > math.exp(1.645 * _spread_of(FACTORS))


def _spread_of(factors: tuple[float, ...]) -> float:
    """sd of ln factor across these tails."""
    logs = [math.log(f) for f in factors]
    mean = sum(logs) / len(logs)
    return math.sqrt(sum((x - mean) ** 2 for x in logs) / len(logs))


def test_an_inspection_updates_only_its_tail(tracked: TestClient, settings: Settings) -> None:
    before = {t: _forecast(tracked, t) for t in ("T0", "NEW")}
    factory = make_session_factory(make_engine(settings.database_url))
    with factory() as session:
        new_id = session.scalar(select(Aircraft.id).where(Aircraft.tail == "NEW"))
        others = {
            (row.aircraft_id, row.crack_samples_m)
            for row in session.scalars(select(Forecast).where(Forecast.aircraft_id != new_id))
        }
    measured = _euler(1.5)
    started = time.perf_counter()
    inspect(tracked, "NEW", LAST_FLIGHT, measured)
    after = _forecast(tracked, "NEW")
    seconds = time.perf_counter() - started
    print(f"inspection to updated forecast: {seconds:.2f} s")
    with factory() as session:
        unchanged = {
            (row.aircraft_id, row.crack_samples_m)
            for row in session.scalars(select(Forecast).where(Forecast.aircraft_id != new_id))
        }
    assert unchanged == others
    assert _forecast(tracked, "T0") == before["T0"]
    assert after["growth"]["factor_p50"] > 1.3
    assert after["crack_length_m"] > before["NEW"]["crack_length_m"]
    assert np.isclose(after["crack_length_m"], measured, rtol=0.03)
