"""Time as engineers read it: horizons from the as-of date, overdue inspect-by, repairs after the
last flight, and the estimated crack over the recorded flights."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import nullcontext
from datetime import date, datetime, timedelta
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from app import budget
from app.config import Settings
from app.db import make_engine, make_session_factory
from app.local_server import wait_for_job
from app.services import models
from app.services.forecasts import risk
from app.services.forecasts.crack_history import crack_history
from app.services.ranking import ranking_rows
from app.tables import Forecast
from app.worker import Worker
from tests.app.conftest import START, add_tail, inspect, serving, settings_in

# The fleet flies 10 days from START; "today" lies 100 days after its first flight.
AS_OF = START.date() + timedelta(days=100)
REPAIRED_AT = START + timedelta(days=20)


def _time(value: str) -> datetime:
    return datetime.fromisoformat(value.replace("Z", "+00:00"))


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[TestClient, Settings]]:
    """FAST (300 MPa, near a_crit within a year), SLOW, REP (repaired after its last flight)
    and MID (repaired halfway through its flights); physics model."""
    settings = settings_in(Path(tmp_path_factory.mktemp("as_of")))
    with serving(settings) as client:
        add_tail(client, "FAST", 40, stress=300.0)
        add_tail(client, "SLOW", 40, stress=100.0)
        add_tail(client, "REP", 40, stress=150.0)
        add_tail(client, "MID", 40, stress=150.0)
        inspect(client, "SLOW", START + timedelta(days=5), 0.00502)
        for tail, at, crack in (
            ("REP", REPAIRED_AT, 0.003),
            ("MID", START + timedelta(days=5), 0.002),
        ):
            body = {
                "inspection_id": f"R-{tail}",
                "inspected_at": at.isoformat(),
                "crack_length_m": 0.0051,
                "repaired": True,
                "crack_after_repair_m": crack,
            }
            assert client.post(f"/aircraft/{tail}/inspections", json=body).status_code == 201
        job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
        assert job["status"] == "succeeded", job["error"]
        yield client, settings


def test_the_projection_runs_through_today_and_the_horizon_after_it(
    fleet: tuple[TestClient, Settings],
) -> None:
    client, _ = fleet
    params = {"horizon_days": 30, "as_of": AS_OF.isoformat()}
    body = client.get("/aircraft/SLOW/forecast", params=params).json()
    origin = _time(body["origin"])
    assert body["as_of"] == f"{AS_OF.isoformat()}T00:00:00Z"
    assert body["last_flown_at"] == body["origin"]
    lead = (AS_OF - origin.date()).days
    points = body["trajectory"]
    assert len(points) == lead + 30 + 1  # SLOW stays far from a_crit
    assert _time(points[0]["date"]) == origin
    today, later = body["crack_as_of"], body["crack_at_horizon"]
    assert _time(today["date"]).date() == AS_OF
    assert _time(later["date"]).date() == AS_OF + timedelta(days=30)
    for point, day in ((today, lead), (later, lead + 30)):
        assert point["date"] == points[day]["date"]
        assert point["crack_length_m"] == points[day]["crack_length_m"]
        assert point["p50"] == pytest.approx(points[day]["p50"], rel=1e-6)  # bands: float32
    assert body["crack_length_m"] < today["crack_length_m"] < later["crack_length_m"]
    # the pinned setting is the default "today"
    pinned = client.get("/aircraft/SLOW/forecast", params={"horizon_days": 30}).json()
    assert pinned["as_of"] == f"{START.date().isoformat()}T00:00:00Z"
    assert len(pinned["trajectory"]) == 31


def test_an_inspect_by_date_before_today_is_overdue(fleet: tuple[TestClient, Settings]) -> None:
    client, _ = fleet
    first = client.get("/aircraft/FAST/forecast", params={"horizon_days": 3650}).json()
    assert first["inspect_by"] is not None and first["overdue"] is False
    due = _time(first["inspect_by"]).date()
    for as_of, overdue in ((due, False), (due + timedelta(days=1), True)):
        params = {"horizon_days": 3650, "as_of": as_of.isoformat()}
        body = client.get("/aircraft/FAST/forecast", params=params).json()
        assert (body["inspect_by"], body["overdue"]) == (first["inspect_by"], overdue)
        ranking = client.get("/fleet/ranking", params=params).json()
        item = next(i for i in ranking["items"] if i["tail"] == "FAST")
        assert (item["inspect_by"], item["overdue"]) == (first["inspect_by"], overdue)
        assert item["crack_as_of_band"] == {
            q: pytest.approx(body["crack_as_of"][q], rel=1e-6) for q in ("p05", "p50", "p95")
        }


def test_a_repair_after_the_last_flight_starts_the_projection(
    fleet: tuple[TestClient, Settings],
) -> None:
    client, _ = fleet
    body = client.get("/aircraft/REP/forecast", params={"horizon_days": 30}).json()
    assert _time(body["origin"]) == REPAIRED_AT
    assert _time(body["last_flown_at"]) < REPAIRED_AT
    assert body["crack_length_m"] == 0.003
    assert _time(body["trajectory"][0]["date"]) == REPAIRED_AT


def test_the_chart_continues_the_estimated_crack_over_the_recorded_flights(
    fleet: tuple[TestClient, Settings],
) -> None:
    client, settings = fleet
    factory = _sessions(settings)
    with factory() as session:
        slow = crack_history(session, "SLOW", settings)
        mid = crack_history(session, "MID", settings)
        few = crack_history(session, "SLOW", settings, max_points=7)
    forecast = client.get("/aircraft/SLOW/forecast", params={"horizon_days": 30}).json()
    assert slow.dates[-1] == _time(forecast["last_flown_at"])
    assert slow.crack_m[-1] == pytest.approx(forecast["crack_length_m"], rel=1e-12)
    assert len(slow.crack_m) == 40 and slow.crack_m == sorted(slow.crack_m)
    assert len(few.crack_m) <= 8 and few.crack_m[-1] == slow.crack_m[-1]
    # MID restarts at 2 mm after its repair (day 5: 20 flights): the curve drops there
    drop = min(range(1, 40), key=lambda i: mid.crack_m[i] - mid.crack_m[i - 1])
    assert mid.dates[drop - 1] < START + timedelta(days=5) <= mid.dates[drop]
    assert mid.crack_m[drop] < 0.0021 < 0.005 < mid.crack_m[drop - 1]
    svg = client.get("/aircraft/MID/forecast.svg").text
    assert 'id="history"' in svg and 'id="as-of"' in svg


def test_a_bad_as_of_is_a_422_naming_it(fleet: tuple[TestClient, Settings]) -> None:
    client, _ = fleet
    answer = client.get("/aircraft/SLOW/forecast", params={"as_of": "yesterday"})
    assert answer.status_code == 422
    assert answer.json()["detail"][0]["loc"] == ["query", "as_of"]


def test_as_of_setting_is_an_iso_date() -> None:
    assert Settings(as_of="2025-01-01").today() == date(2025, 1, 1)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="as_of"):
        Settings(as_of="soon")  # type: ignore[arg-type]


def _sessions(settings: Settings) -> sessionmaker[Session]:
    return make_session_factory(make_engine(settings.database_url))


def _rows_risk(factory: sessionmaker[Session], settings: Settings, day: date) -> list[object]:
    """Each stored forecast row's risk cached for `day` (None where none is)."""
    with factory() as session:
        rows = session.scalars(select(Forecast)).all()
        return [risk.cached_risk(r, settings.forecast_horizon_days, settings, day) for r in rows]


def test_an_idle_worker_samples_a_new_days_risk_and_the_next(
    fleet: tuple[TestClient, Settings],
) -> None:
    _, settings = fleet
    later = settings.model_copy(update={"as_of": AS_OF + timedelta(days=7)})
    factory = _sessions(settings)

    def cached(days: int) -> list[bool]:
        return [r is not None for r in _rows_risk(factory, later, AS_OF + timedelta(days=days))]

    assert cached(7) and not any(cached(7)) and not any(cached(8))
    Worker(factory, later, name="test").warm_today()
    assert all(cached(7)) and all(cached(8))  # today's and tomorrow's, ahead of the rankings


def test_a_stopping_worker_ends_its_sampling_at_the_next_piece(
    fleet: tuple[TestClient, Settings],
) -> None:
    """Worker.stop sets the event its cache thread samples under (app.budget.until): a server
    stopped while the worker samples the fleet's risk stops at once, not after a 10-s join."""
    _, settings = fleet
    day = AS_OF + timedelta(days=9)
    later = settings.model_copy(update={"as_of": day})
    factory = _sessions(settings)
    stopping = threading.Event()
    stopping.set()
    with budget.until(stopping), pytest.raises(budget.Stopped):
        Worker(factory, later, name="test").warm_today()
    found = _rows_risk(factory, later, day)
    assert found and all(r is None for r in found)


def test_a_worker_samples_in_pieces_that_change_no_number(
    fleet: tuple[TestClient, Settings], monkeypatch: pytest.MonkeyPatch
) -> None:
    """In a worker thread the fleet's risk is sampled a few tails a piece (app.budget.
    tails_per_march; one here): each tail's risk equals the one sampled in a single piece."""
    _, settings = fleet
    factory = _sessions(settings)
    monkeypatch.setattr(budget, "STOPPABLE_TAILS", 1)
    day, horizon = AS_OF + timedelta(days=11), settings.forecast_horizon_days

    def sampled(in_a_worker: bool) -> list[risk.Risk | None]:
        with factory() as session:
            version = models.require_active_version(session)
            posterior = models.load_posterior(session, version)
            rows = ranking_rows.cached_tails(session, version, settings, states=True)
            states = [row.state for row in rows if row.state is not None]
            with budget.until(threading.Event()) if in_a_worker else nullcontext():
                risk.fill_risk(posterior, states, horizon, settings, bands=False, as_of=day)
            return [risk.cached_risk(state, horizon, settings, day) for state in states]

    pieces, whole = sampled(True), sampled(False)
    assert len(whole) >= 3 and None not in whole and pieces == whole


def test_an_as_of_before_the_origin_says_the_answer_starts_there(
    fleet: tuple[TestClient, Settings],
) -> None:
    """An as_of before the tail's data ended answered from its last flight without saying so
    (issue 42): the answer names both dates; on or after the origin's date it says nothing."""
    client, _ = fleet
    early = {"horizon_days": 30, "as_of": "2023-06-01"}  # before SLOW's first flight
    body = client.get("/aircraft/SLOW/forecast", params=early).json()
    origin = _time(body["origin"])
    assert body["as_of_note"].startswith(
        f"as_of 2023-06-01 lies before this forecast's origin {origin.date()}"
    )
    assert _time(body["crack_as_of"]["date"]) == origin  # what the note says
    assert len(body["trajectory"]) == 31  # the horizon counts from the origin
    planned = {
        "planned": {"flights_per_day": 4.0, "missions": [{"stress_range_mpa": 100.0, "share": 1.0}]}
    }
    posted = client.post("/aircraft/SLOW/forecast", params=early, json=planned)
    assert posted.json()["as_of_note"] == body["as_of_note"]
    for as_of in (origin.date(), AS_OF):
        later = {"horizon_days": 30, "as_of": as_of.isoformat()}
        assert "as_of_note" not in client.get("/aircraft/SLOW/forecast", params=later).json()
