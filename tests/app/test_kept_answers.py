"""What a process keeps between requests never outlives the state it came from: forecasts
served from their kept answers (app.services.forecasts.forecast_answers), the ranking from its kept answer
and order (app.services.ranking.ranking_answers, app.services.ranking.order), all under their rows' stamps
(app.tables.Forecast.stamp; the ranking under their fingerprint, app.services.forecasts.cache_rows), an
aircraft's answer with several locations too (its lines read from each location's row), and
keys found valid for key_cache_seconds (app.auth).

Each change is made after the kept answer has been served at least once; the next answer must
equal one computed from scratch (nothing kept) and differ from the one served before, so an
answer kept past its state fails."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from datetime import timedelta
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select, update

from app.local_server import wait_for_job
from app.services import keys
from app.services.forecasts import cache_advance, risk
from app.services.records import locations
from app.tables import DEFAULT_LOCATION_ID, Aircraft, Forecast
from tests.app.conftest import (
    START,
    add_tail,
    bearer,
    forget_kept_answers,
    inspect,
    later_flights,
    repair,
    retrained,
    serving,
    settings_for,
)
from tests.app.snapshots import copied_for_each_test, copy_of, serving_copy

FORECAST = "/aircraft/MID/forecast"


def _store_fleet(client: TestClient) -> None:
    """Two tails of 40 flights (LOW inspected) and the physics model active; the changes are
    made to MID, whose rows new flights advance (an update of the row, not a new one)."""
    add_tail(client, "LOW", 40, stress=100.0)
    add_tail(client, "MID", 40, stress=150.0)
    inspect(client, "LOW", START + timedelta(days=10, hours=1), 0.0051)
    _retrain(client)


stored_database, fleet = copied_for_each_test("fleet", _store_fleet)


def _retrain(client: TestClient) -> int:
    return int(retrained(client)["result"]["model_version"])


def _served(client: TestClient, path: str, **params: Any) -> dict[str, Any]:
    answer = client.get(path, params=params)
    assert answer.status_code == 200, answer.text
    body: dict[str, Any] = answer.json()
    return body


def _from_scratch(client: TestClient, path: str, **params: Any) -> dict[str, Any]:
    forget_kept_answers()
    return _served(client, path, **params)


CHANGES: dict[str, Callable[[TestClient], Any]] = {
    "new flights": lambda c: later_flights(c, "MID"),
    "corrected flight": lambda c: c.patch(
        "/aircraft/MID/flights/F0040", json={"stress_range_mpa": 300.0}
    ),
    "deleted flight": lambda c: c.delete("/aircraft/MID/flights/F0040"),
    "repair": lambda c: repair(c, "MID"),
    "new initial crack": lambda c: c.put("/aircraft/MID", json={"initial_crack_m": 0.006}),
}


def _across(
    client: TestClient, change: Callable[[TestClient], Any], path: str, **params: Any
) -> tuple[dict[str, Any], dict[str, Any]]:
    """The answer at `path` before and after `change`: kept before it (served twice alike),
    the change accepted, and the answer after it equal to one made from scratch."""
    before = _served(client, path, **params)
    assert _served(client, path, **params) == before  # kept, and the same answer
    answer = change(client)
    assert answer is None or answer.status_code in (200, 201), answer.text
    after = _served(client, path, **params)
    assert after == _from_scratch(client, path, **params)
    return before, after


@pytest.mark.parametrize("change", sorted(CHANGES))
def test_a_kept_forecast_never_outlives_its_tail(fleet: TestClient, change: str) -> None:
    before, after = _across(fleet, CHANGES[change], FORECAST)
    assert after != before
    assert _served(fleet, FORECAST) == after


def test_a_kept_answer_is_per_horizon_and_as_of_date(fleet: TestClient) -> None:
    near = _served(fleet, FORECAST, horizon_days=30)
    far = _served(fleet, FORECAST, horizon_days=60)
    later = _served(fleet, FORECAST, horizon_days=30, as_of="2024-03-01")
    assert near["horizon_days"] == 30 and far["horizon_days"] == 60
    assert later["as_of"].startswith("2024-03-01") and near["as_of"] != later["as_of"]
    assert _served(fleet, FORECAST, horizon_days=30) == near


def test_another_active_version_is_served_at_once(fleet: TestClient) -> None:
    """A retrain stores version 2; activating it, then version 1 again (a rollback), serves
    each one's forecasts and ranking at once."""
    _retrain(fleet)
    for version in (2, 1):
        before = _served(fleet, FORECAST)
        assert _served(fleet, "/fleet/ranking")["model_version"] == before["model_version"]
        if before["model_version"] == version:
            continue
        assert fleet.post(f"/models/{version}/activate").status_code == 200
        after = _served(fleet, FORECAST)
        assert after["model_version"] == version
        assert after == _from_scratch(fleet, FORECAST)
        assert _served(fleet, "/fleet/ranking")["model_version"] == version


def test_every_write_of_a_cached_row_gives_it_a_new_stamp(fleet: TestClient) -> None:
    """Inserted rows, ORM updates and update() statements alike (cache_advance writes with
    update() statements; a store of risk sampled from the row itself keeps its stamp:
    cache_rows.store_risk, tests/app/test_ranking_delta.py)."""
    _served(fleet, FORECAST)
    factory = fleet.app.state.session_factory  # type: ignore[attr-defined]
    with factory() as session:
        row = session.scalars(select(Forecast)).first()
        assert row is not None and row.stamp is not None
        seen = {row.stamp}
        where = (Forecast.aircraft_id == row.aircraft_id) & (
            Forecast.model_version == row.model_version
        )
        session.execute(
            update(Forecast)
            .where(where)
            .values(risk={})
            .execution_options(synchronize_session=False)
        )
        session.commit()
        seen.add(session.scalar(select(Forecast.stamp).where(where)))
        row = session.scalars(select(Forecast).where(where)).one()
        row.flights_per_day = row.flights_per_day + 1.0
        session.commit()
        seen.add(session.scalar(select(Forecast.stamp).where(where)))
    assert len(seen) == 3 and None not in seen


@pytest.mark.parametrize("change", ["new flights", "corrected flight", "new initial crack"])
def test_the_kept_ranking_never_outlives_a_row(fleet: TestClient, change: str) -> None:
    before, after = _across(fleet, CHANGES[change], "/fleet/ranking", by="crack")
    assert after != before


def test_the_kept_ranking_takes_in_a_new_tail(fleet: TestClient) -> None:
    assert _served(fleet, "/fleet/ranking")["total"] == 2
    add_tail(fleet, "NEW", 40, stress=200.0)
    after = _served(fleet, "/fleet/ranking", by="crack")
    assert after["total"] == 3 and after["items"][0]["tail"] == "NEW"


def _inspect_wing(
    client: TestClient, tail: str, inspection_id: str, hours: int, crack_m: float
) -> None:
    body = {
        "inspection_id": inspection_id,
        "inspected_at": (START + timedelta(days=10, hours=hours)).isoformat(),
        "crack_length_m": crack_m,
        "location": "wing",
    }
    assert client.post(f"/aircraft/{tail}/inspections", json=body).status_code == 201


def _wing_inspection(client: TestClient) -> None:
    _inspect_wing(client, "MID", "W2", 3, 0.0031)


# changes that move the wing's row (or every location's) but not always the default one's
WING_CHANGES: dict[str, Callable[[TestClient], Any]] = {
    "new flights": lambda c: later_flights(c, "MID"),
    "replaced wing entry": lambda c: c.put(
        "/locations/wing", json={"stress_factor": 1.6, "initial_crack_m": 0.002}
    ),
    "wing inspection": _wing_inspection,
}


@pytest.fixture(scope="module")
def stored_two_locations(
    stored_database: str, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[str]:
    """The fleet with a wing location (1.5 x the stress from a smaller crack) inspected on
    LOW and both locations' versions active (copied for each test)."""
    with copy_of(stored_database, tmp_path_factory.mktemp("two_locations")) as url:
        with serving(settings_for(url)) as client:
            assert client.put(
                "/locations/wing", json={"stress_factor": 1.5, "initial_crack_m": 0.002}
            )
            _inspect_wing(client, "LOW", "W1", 1, 0.0030)
            accepted = client.post("/models/retrain").json()
            for job in accepted["jobs"].values():
                assert wait_for_job(client, job)["status"] == "succeeded"
        yield url


@pytest.fixture
def two_locations(stored_two_locations: str, tmp_path: Path) -> Iterator[TestClient]:
    with serving_copy(stored_two_locations, tmp_path) as client:
        yield client


@pytest.mark.parametrize("change", sorted(WING_CHANGES))
def test_an_aircraft_answer_never_outlives_any_of_its_locations(
    two_locations: TestClient, change: str
) -> None:
    before, after = _across(two_locations, WING_CHANGES[change], FORECAST)
    assert {line["location"] for line in before["locations"]} == {"default", "wing"}
    wing = [line for line in after["locations"] if line["location"] == "wing"]
    assert wing != [line for line in before["locations"] if line["location"] == "wing"]
    assert _served(two_locations, FORECAST) == after


@pytest.mark.parametrize("change", sorted(WING_CHANGES))
def test_the_kept_ranking_of_several_locations_never_outlives_a_row(
    two_locations: TestClient, change: str
) -> None:
    before, after = _across(two_locations, WING_CHANGES[change], "/fleet/ranking", by="crack")
    assert {item["location"] for item in before["items"]} == {"default", "wing"}
    assert after != before


def test_another_locations_bands_are_its_forecasts_and_keep_the_stamp(
    two_locations: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An ingest samples the default location's risk and bands, the wing's risk alone (an
    aircraft's answer and the ranking read no more of it), and leaves the wing's bands to its
    own forecast, not to the worker; that forecast's store keeps the row's stamp, and every
    answer is the one made from scratch."""
    sampled: list[tuple[tuple[int, ...], bool]] = []

    def spy(*args: Any, bands: bool, **kwargs: Any) -> None:
        if threading.current_thread().name != "fleetpinn-cache":  # the request's own
            sampled.append((tuple(sorted({s.location_id for s in args[1]})), bands))
        risk.fill_risk(*args, bands=bands, **kwargs)

    aircraft = _served(two_locations, FORECAST)
    monkeypatch.setattr(cache_advance, "fill_risk", spy)
    later_flights(two_locations, "MID")
    factory = two_locations.app.state.session_factory  # type: ignore[attr-defined]
    with factory() as session:
        wing = locations.location_id(session, "wing")
    assert sorted(sampled) == [((DEFAULT_LOCATION_ID,), True), ((wing,), False)]
    mid = select(Aircraft.id).where(Aircraft.tail == "MID").scalar_subquery()
    row = select(Forecast.stamp, Forecast.bands).where(
        Forecast.location_id == wing, Forecast.aircraft_id == mid
    )
    with factory() as session:
        stamp, bands = session.execute(row).one()
    assert bands == {}  # none of today's, and not pending: the worker leaves it
    after = _served(two_locations, FORECAST)
    assert after != aircraft and after == _from_scratch(two_locations, FORECAST)
    wing_path = "/aircraft/MID/locations/wing/forecast"
    assert _served(two_locations, wing_path) == _from_scratch(two_locations, wing_path)
    with factory() as session:
        assert session.execute(row).one()[0] == stamp
        assert session.execute(row).one()[1] != {}


@pytest.mark.parametrize("ttl", [0.0, 0.5])
def test_a_revoked_key_is_refused_within_key_cache_seconds(database_url: str, ttl: float) -> None:
    settings = settings_for(database_url).model_copy(update={"key_cache_seconds": ttl})
    with serving(settings) as client:
        factory = client.app.state.session_factory  # type: ignore[attr-defined]
        with factory() as session:
            key = keys.create_key(session, role="read", name="ops").key
        assert client.get("/aircraft", headers=bearer(key)).status_code == 200
        with factory() as session:
            keys.revoke_key(session, "ops")
        revoked = time.monotonic()
        while client.get("/aircraft", headers=bearer(key)).status_code == 200:
            assert time.monotonic() - revoked < ttl, "a revoked key was served past its time"
            time.sleep(0.02)
        assert time.monotonic() - revoked < ttl + 0.5
