"""The forecast cache advances a tail over its new flights in the ingest's own transaction: the
advanced row equals the one recomputed from the whole history; a flight landing before the row's
origin recomputes it."""

from __future__ import annotations

import math
import time
from datetime import timedelta
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select, update
from sqlalchemy.orm import Session

from app.config import Settings
from app.db import make_engine, make_session_factory
from app.local_server import wait_for_job
from app.services.dates import days_ahead
from app.services.forecasts import forecast_cache
from app.services.forecasts.risk import cached_band, cached_risk
from app.tables import Aircraft, Forecast
from tests.app.conftest import START, add_tail, inspect, serving, settings_for
from tests.app.snapshots import copied_for_each_test, served_settings

C, M, A0 = 1.5e-11, 3.8, 0.005
STRESS, FLIGHTS = 250.0, 300
FACTORS = (0.7, 0.9, 1.1, 1.4)


def _euler(factor: float, flights: int = FLIGHTS) -> float:
    crack = A0
    for _ in range(flights):
        crack += factor * C * (STRESS * math.sqrt(math.pi * crack)) ** M
    return crack


def _track(
    client: TestClient, factors: tuple[float, ...], retrain: dict[str, Any], rounds: int = 1
) -> None:
    """Tails that grow at their own rates, each inspected `rounds` times (the last after its
    last flight), one never inspected; retrained."""
    for i, factor in enumerate(factors):
        add_tail(client, f"T{i}", FLIGHTS, stress=STRESS)
        for k in range(rounds, 0, -1):
            flown = FLIGHTS * (rounds - k + 1) // rounds
            at = START + timedelta(hours=6 * (flown - 1), minutes=30)
            inspect(client, f"T{i}", at, _euler(factor, flown))
    add_tail(client, "NEW", FLIGHTS, stress=STRESS)
    job = wait_for_job(client, client.post("/models/retrain", json=retrain).json()["job_id"])
    assert job["status"] == "succeeded", job["error"]


def _store_tracked(client: TestClient) -> None:
    """A tracked physics version (the default kernel of the tests' settings)."""
    _track(client, FACTORS, {})


stored_database, tracked = copied_for_each_test("tracked", _store_tracked)


@pytest.fixture
def settings(tracked: TestClient) -> Settings:
    """The settings the copy is served with."""
    return served_settings(tracked)


def _new_flights(start_hours: int, count: int, prefix: str) -> list[dict[str, Any]]:
    return [
        {
            "flight_id": f"{prefix}{k}",
            "flown_at": (START + timedelta(hours=start_hours + 6 * k)).isoformat(),
            "stress_range_mpa": 180.0 + 20.0 * k,
        }
        for k in range(count)
    ]


def _row(session: Session, tail: str) -> Forecast:
    aircraft_id = session.scalars(select(Aircraft.id).where(Aircraft.tail == tail)).one()
    row = session.scalars(select(Forecast).where(Forecast.aircraft_id == aircraft_id)).one()
    session.expunge(row)
    return row


def _recomputed(session: Session, row: Forecast, settings: Settings) -> Forecast:
    forecast_cache.invalidate(session, [row.aircraft_id])
    session.commit()
    forecast_cache.refresh(session, row.model_version, settings, aircraft_ids=[row.aircraft_id])
    return _row(session, _tail(session, row.aircraft_id))


def _tail(session: Session, aircraft_id: int) -> str:
    return session.scalars(select(Aircraft.tail).where(Aircraft.id == aircraft_id)).one()


def _assert_same_state(advanced: Forecast, recomputed: Forecast) -> None:
    assert advanced.flights_flown == recomputed.flights_flown
    assert advanced.origin == recomputed.origin
    assert advanced.first_flown_at == recomputed.first_flown_at
    assert advanced.flights_per_day == pytest.approx(recomputed.flights_per_day, rel=1e-12)
    assert advanced.recent_stress_mpa == recomputed.recent_stress_mpa
    assert advanced.crack_length_m == pytest.approx(recomputed.crack_length_m, rel=1e-12)
    assert advanced.flights_to_critical == recomputed.flights_to_critical
    assert advanced.critical_date == recomputed.critical_date
    assert advanced.growth == recomputed.growth
    assert advanced.growth_samples == recomputed.growth_samples
    samples = np.frombuffer(advanced.crack_samples_m or b"", np.float64)
    expected = np.frombuffer(recomputed.crack_samples_m or b"", np.float64)
    # the recompute interpolates samples between marched growth factors
    # (model.fleet_sampling): advancing the stored samples keeps that interpolation's error
    np.testing.assert_allclose(samples, expected, rtol=1e-9)
    assert set(recomputed.risk or {}) <= set(advanced.risk or {})
    for key, risk in (recomputed.risk or {}).items():
        mine = (advanced.risk or {})[key]
        assert mine["prob_critical"] == pytest.approx(risk["prob_critical"], abs=1e-12)
        np.testing.assert_allclose(mine["crack_at_horizon"], risk["crack_at_horizon"], rtol=1e-9)


def _assert_stored_as_recomputed(settings: Settings, tail: str, flights_flown: int) -> None:
    """The tail's stored row has flown flights_flown and equals a recompute of it."""
    factory = make_session_factory(make_engine(settings.database_url))
    with factory() as session:
        row = _row(session, tail)
        assert row.flights_flown == flights_flown
        _assert_same_state(row, _recomputed(session, row, settings))


@pytest.mark.parametrize("tail", ["T2", "NEW"])
def test_new_flights_advance_the_cached_tail(
    tracked: TestClient, settings: Settings, tail: str
) -> None:
    factory = make_session_factory(make_engine(settings.database_url))
    with factory() as session:
        before = _row(session, tail)
    after_origin = int((before.origin - START).total_seconds() // 3600) + 6
    answer = tracked.post(f"/aircraft/{tail}/flights", json=_new_flights(after_origin, 3, "A"))
    assert answer.status_code == 201, answer.text
    with factory() as session:
        advanced = _row(session, tail)  # by the ingest itself: no reader has asked yet
        assert advanced.flights_flown == FLIGHTS + 3
        assert advanced.origin == before.origin + timedelta(hours=6 * 3)
        _assert_same_state(advanced, _recomputed(session, advanced, settings))
    forecast = tracked.get(f"/aircraft/{tail}/forecast", params={"horizon_days": 30})
    assert forecast.status_code == 200, forecast.text
    assert forecast.json()["flights_flown"] == FLIGHTS + 3


def test_the_ingest_stores_the_bands_and_the_worker_tomorrows_risk(
    tracked: TestClient, settings: Settings
) -> None:
    """The ingest's own transaction stores the advanced row with today's risk and daily bands:
    no forecast or ranking of today samples anything after it.  Tomorrow's risk follows from
    the worker's cache thread, and its write keeps the row's stamp (cache_rows.store_risk)."""
    after_origin = 6 * FLIGHTS + 6
    answer = tracked.post("/aircraft/T2/flights", json=_new_flights(after_origin, 2, "W"))
    assert answer.status_code == 201, answer.text
    factory = make_session_factory(make_engine(settings.database_url))
    today, tomorrow = days_ahead(settings)
    horizon = settings.forecast_horizon_days
    with factory() as session:
        row = _row(session, "T2")
    assert row.flights_flown == FLIGHTS + 2
    assert cached_band(row, horizon, settings, today) is not None
    assert cached_risk(row, horizon, settings, today) is not None
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        with factory() as session:
            ahead = _row(session, "T2")
        if cached_risk(ahead, horizon, settings, tomorrow) is not None:
            break
        time.sleep(0.05)
    assert cached_risk(ahead, horizon, settings, tomorrow) is not None
    assert ahead.stamp == row.stamp and ahead.flights_flown == row.flights_flown


def test_the_worker_samples_a_row_stored_without_bands(
    tracked: TestClient, settings: Settings
) -> None:
    """Rows an older release's ingest stored without their bands (and tomorrow's risk) are
    sampled by the worker's cache thread (cache_advance.fill_pending)."""
    factory = make_session_factory(make_engine(settings.database_url))
    with factory() as session:
        row = _row(session, "T2")
        session.execute(
            update(Forecast)
            .where(Forecast.aircraft_id == row.aircraft_id)
            .values(bands=None, risk={})  # tables.NULLABLE_JSON: SQL NULL, not JSON 'null'
            .execution_options(synchronize_session=False)
        )
        session.commit()
    today, tomorrow = days_ahead(settings)
    horizon = settings.forecast_horizon_days
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        with factory() as session:
            row = _row(session, "T2")
        if row.bands is not None:
            break
        time.sleep(0.05)
    assert cached_band(row, horizon, settings, today) is not None
    assert cached_risk(row, horizon, settings, tomorrow) is not None


def test_a_tracked_hybrid_advances_under_its_weight_posterior(database_url: str) -> None:
    """A residual version whose tails scatter stores one mode of its weights' posterior; the
    samples that share a weight draw (model.prognosis.weight_draws) advance as they were
    filled, so the advanced row equals the recomputed one.  Two rounds of inspections: with
    one, the retrain keeps the physics where tails scatter (model.kernel_choice)."""
    settings = settings_for(database_url)
    factors = (0.7, 0.85, 1.0, 1.15, 1.3, 1.45)
    with serving(settings) as client:
        _track(client, factors, {"kernel": "residual", "holdout_fraction": 0}, rounds=2)
        version = client.get("/models").json()[-1]
        assert version["metrics"]["tracking"]["growth_sd"] > 0.02
        assert version["training"]["posterior"]["modes"] == 1
        answer = client.post("/aircraft/T2/flights", json=_new_flights(6 * FLIGHTS + 6, 3, "H"))
        assert answer.status_code == 201, answer.text
        assert client.get("/aircraft/T2/forecast").status_code == 200
        _assert_stored_as_recomputed(settings, "T2", FLIGHTS + 3)


def test_a_flight_before_a_stored_inspection_recomputes_the_tail(
    tracked: TestClient, settings: Settings
) -> None:
    """T1's inspection lies 30 min after its last flight; a flight recorded between them
    changes the inspection's flight count, so the row is recomputed, not advanced."""
    flown = START + timedelta(hours=6 * (FLIGHTS - 1), minutes=15)
    between = [{"flight_id": "B1", "flown_at": flown.isoformat(), "stress_range_mpa": 200.0}]
    assert tracked.post("/aircraft/T1/flights", json=between).status_code == 201
    assert tracked.get("/aircraft/T1/forecast").status_code == 200
    _assert_stored_as_recomputed(settings, "T1", FLIGHTS + 1)


def test_a_flight_before_the_origin_recomputes_the_tail(
    tracked: TestClient, settings: Settings
) -> None:
    answer = tracked.post("/aircraft/T1/flights", json=_new_flights(1, 1, "PAST"))
    assert answer.status_code == 201, answer.text
    ranking = tracked.get("/fleet/ranking", params={"by": "crack"})
    assert ranking.status_code == 200, ranking.text
    _assert_stored_as_recomputed(settings, "T1", FLIGHTS + 1)


def test_the_retrain_refill_equals_a_recompute(tracked: TestClient, settings: Settings) -> None:
    """The retrain's refill reuses its history and its tails' growth posteriors
    (cache_fill.Known); every row equals one recomputed from the database alone."""
    factory = make_session_factory(make_engine(settings.database_url))
    with factory() as session:
        for tail in [f"T{i}" for i in range(len(FACTORS))] + ["NEW"]:
            row = _row(session, tail)
            again = _recomputed(session, row, settings)
            assert again.growth == row.growth
            assert again.growth_samples == row.growth_samples
            assert again.crack_samples_m == row.crack_samples_m
            assert again.risk == row.risk
