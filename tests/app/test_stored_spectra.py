"""The service's retrain reads the stored cycles: a Walker fleet uploaded as its cycle file and
retrained through the job queue learns gamma, and its forecasts weigh the cycles under the
learned law; a fleet sent as one range per flight trains exactly as before."""

from __future__ import annotations

import io
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.config import Settings
from app.db import make_engine
from app.local_server import wait_for_job
from app.services.records import locations
from app.services.records.history import load_history
from app.services.records.stored_spectra import for_training, with_stored_cycles
from app.tables import DEFAULT_LOCATION, Aircraft, Forecast
from model.cycle_counting import FlightCycles
from model.fleet import FleetConfig, inspect_at
from model.growth_laws import GrowthConstants
from model.physics import ParisLaw
from model.spectra_fleet import SpectraFleet, SpectraFleetConfig, generate_spectra_fleet
from tests.app.conftest import serving, settings_in

# model/tests' small fast-growing fleet (tests/model/test_spectra.py), 12 tails of 3 years
SMALL = FleetConfig(aircraft_per_mix=4, years=3, flights_per_day=2, law=ParisLaw(c=7.5e-11), seed=3)


@pytest.fixture(scope="module")
def spectra() -> SpectraFleet:
    return generate_spectra_fleet(SpectraFleetConfig(SMALL, gamma=0.6, switch_year=1.5))


def _settings(folder: Path) -> Settings:
    """Walker's law from the settings' gamma 1 (Paris), C and m learned, the physics kernel,
    today the day after the fleet's last flight."""
    return settings_in(folder).model_copy(
        update={
            "growth_law": "walker",
            "walker_gamma": 1.0,
            "learn_paris": True,
            "as_of": datetime(2023, 1, 2, tzinfo=UTC).date(),
        }
    )


def _upload(client: TestClient, frame: pd.DataFrame, name: str) -> None:
    body = frame.to_csv(index=False).encode()
    answer = client.post("/flights/upload", files={"file": (name, io.BytesIO(body), "text/csv")})
    assert answer.status_code == 201, answer.text


def _inspect_all(client: TestClient, spectra: SpectraFleet) -> None:
    """Every tail inspected without error after 1, 2 and 3 years."""
    fleet = spectra.fleet
    fpy = fleet.config.flights_per_year
    sample = inspect_at(fleet, np.arange(fleet.size), np.array([fpy, 2 * fpy, 3 * fpy - 1]))
    frame = fleet.inspections_frame(sample)
    for tail, rows in frame.groupby("tail"):
        body = [
            {
                "inspection_id": row.inspection_id,
                "inspected_at": row.inspected_at.isoformat(),
                "crack_length_m": row.crack_length_m,
            }
            for row in rows.itertuples()
        ]
        answer = client.post(f"/aircraft/{tail}/inspections", json=body)
        assert answer.status_code == 201, answer.text


def _retrain(client: TestClient) -> dict[str, Any]:
    accepted = client.post("/models/retrain", json={"holdout_fraction": 0})
    job = wait_for_job(client, accepted.json()["job_id"], timeout_s=300)
    assert job["status"] == "succeeded", job["error"]
    return job


def _recent_stress(settings: Settings, tail: str) -> np.ndarray:
    """The ranges the tail's cached forecast resamples its future from (in flight order)."""
    engine = make_engine(settings.database_url)
    with Session(engine) as session:
        recent = session.scalar(
            select(Forecast.recent_stress_mpa)
            .join(Aircraft, Aircraft.id == Forecast.aircraft_id)
            .where(Aircraft.tail == tail)
        )
    engine.dispose()
    assert recent is not None
    return np.frombuffer(recent, dtype=np.float64)


def test_a_retrain_learns_walkers_gamma_from_the_stored_cycles_and_forecasts_with_them(
    tmp_path: Path, spectra: SpectraFleet
) -> None:
    settings = _settings(tmp_path)
    channels = (spectra.cycles.stress_range_mpa, spectra.cycles.load_ratio, spectra.cycles.count)
    last = FlightCycles(*(c[0, -1].numpy() for c in channels))  # N001's last flight
    last = FlightCycles(*(v[last.count > 0] for v in last.columns))
    later = FlightCycles(np.array([60.0, 80.0]), np.array([-0.1, 0.6]), np.array([1.0, 5.0]))
    with serving(settings) as client:
        _upload(client, spectra.cycles_frame(), "cycles.csv")
        _inspect_all(client, spectra)
        job = _retrain(client)
        learned = job["metrics"]["growth_law"]["gamma"]
        paris = job["metrics"]["paris"]
        constants = GrowthConstants(paris["c"], paris["m"], learned)
        # the cached forecast resamples its future from the tail's flights' cycles under the
        # learned law, not from the ranges stored under the settings' gamma 1
        cached = _recent_stress(settings, "N001")
        assert cached[-1] == pytest.approx(last.equivalent_range("walker", constants), rel=1e-9)
        # and a flight sent as cycles afterwards advances it the same way
        flight = {
            "flight_id": "LATER",
            "flown_at": "2023-01-01T12:00:00Z",
            "cycles": [
                {"stress_range_mpa": r, "load_ratio": q, "count": n}
                for r, q, n in zip(*(v.tolist() for v in later.columns), strict=True)
            ],
        }
        assert client.post("/aircraft/N001/flights", json=[flight]).status_code == 201
        advanced = _recent_stress(settings, "N001")
    assert job["metrics"]["growth_law"]["name"] == "walker"
    assert abs(learned - 0.6) < 0.05  # from 1: the stored ranges alone carry no load ratio
    assert abs(paris["m"] - spectra.law.m) < 0.15
    assert job["metrics"]["train"]["median_abs_pct_error"] < 1.0
    assert advanced[-2] == cached[-1]  # the window moved on by the new flight
    assert advanced[-1] == pytest.approx(later.equivalent_range("walker", constants), rel=1e-9)
    ingested = later.equivalent_range("walker", settings.law().constants)  # what was stored
    assert abs(advanced[-1] / ingested - 1) > 1e-2


def test_one_range_per_flight_trains_as_before(tmp_path: Path, spectra: SpectraFleet) -> None:
    """No stored cycles: the evidence is the history itself, and gamma stays the settings'."""
    settings = _settings(tmp_path)
    flights = spectra.fleet.flights_frame()
    flights["stress_range_mpa"] = spectra.paris_equivalent_mpa().reshape(-1)
    with serving(settings) as client:
        _upload(client, flights, "flights.csv")
        _inspect_all(client, spectra)
        job = _retrain(client)
    assert job["metrics"]["growth_law"]["gamma"] == 1.0
    engine = make_engine(settings.database_url)
    with Session(engine) as session:
        ids = list(session.scalars(select(Aircraft.id).order_by(Aircraft.id)))
        history = load_history(session, ids, initial_crack_m=0.005)
        assert history is not None
        law = locations.physics(locations.get_location(session, DEFAULT_LOCATION), settings).law
        assert for_training(session, history, "walker", law, True) is history
        assert with_stored_cycles(session, history, "walker", law.constants) is history
    engine.dispose()


def test_a_location_sees_each_flights_cycles_scaled_as_its_range(tmp_path: Path) -> None:
    """At a location whose factor is 1.1 for mission M1 and 0.9 else, a flight's cycles are
    scaled by its mission's factor, so their reduced range is the location's range; a flight
    sent as one range keeps the range the location sees."""
    settings = _settings(tmp_path)
    cycles = [
        {"stress_range_mpa": 100.0, "load_ratio": -0.1},
        {"stress_range_mpa": 40.0, "load_ratio": 0.6, "count": 3},
    ]
    flights = [
        {"flight_id": "A", "flown_at": "2024-01-01T00:00:00Z", "mission": "M1", "cycles": cycles},
        {"flight_id": "B", "flown_at": "2024-01-01T06:00:00Z", "mission": "M2", "cycles": cycles},
        {"flight_id": "C", "flown_at": "2024-01-01T12:00:00Z", "stress_range_mpa": 80.0},
    ]
    with serving(settings) as client:
        body = {"stress_factor": 0.9, "stress_factor_by_mission": {"M1": 1.1}}
        assert client.put("/locations/splice", json=body).status_code in (200, 201)
        assert client.put("/aircraft/N1").status_code == 201
        assert client.post("/aircraft/N1/flights", json=flights).status_code == 201
    walker = GrowthConstants(1e-10, 3.5, 0.5)
    sent = FlightCycles(np.array([100.0, 40.0]), np.array([-0.1, 0.6]), np.array([1.0, 3.0]))
    own = sent.equivalent_range("walker", walker)
    engine = make_engine(settings.database_url)
    with Session(engine) as session:
        splice = locations.get_location(session, "splice")
        ids = list(session.scalars(select(Aircraft.id)))
        history = load_history(session, ids, initial_crack_m=0.005, location_id=splice.id)
        assert history is not None
        read = with_stored_cycles(session, history, "walker", walker)
    engine.dispose()
    assert read.data.loads.stress_range_mpa[0].tolist() == pytest.approx(
        [1.1 * own, 0.9 * own, 0.9 * 80.0], rel=1e-12
    )
    assert read.data.flights["stress_range_mpa"].tolist() == pytest.approx(
        [1.1 * own, 0.9 * own, 0.9 * 80.0], rel=1e-12
    )
    cycles_read = read.segments.loads.cycles
    assert cycles_read is not None
    assert cycles_read.stress_range_mpa[0, 0, :2].tolist() == pytest.approx([110.0, 44.0])
    assert cycles_read.load_ratio[0, 2, 0] == 0.0 and cycles_read.count[0, 2, :].tolist() == [
        1.0,
        0.0,
    ]
