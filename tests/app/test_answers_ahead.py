"""Each API process makes the tails' forecasts before they are asked (app.services.
forecasts.answers_ahead): after a version's activation and after a tail's ingest, the answer a request
would make is already kept, it is the answer made from scratch, and the thread that makes
them runs below the request threads; a tail whose row is missing is left to its readers."""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from datetime import timedelta

import pytest
from fastapi.testclient import TestClient

from app import budget, commands
from app.config import Settings
from app.local_server import wait_for_job
from app.routes.forecasts import encoded_body
from app.services.forecasts import forecast as forecast_service
from app.services.forecasts import forecast_answers
from app.services.forecasts.answers_ahead import AnswersAhead
from tests.app.conftest import (
    AS_OF,
    START,
    add_tail,
    forget_kept_answers,
    inspect,
    later_flights,
    repair,
    retrained,
    serving,
    settings_for,
)

# alone after the parallel run (Makefile pytest): reads a thread's priority and waits for answers
# made in the background
pytestmark = pytest.mark.serial

HORIZON = 365
TAILS = ("LOW", "MID")


@pytest.fixture
def client(settings: Settings) -> Iterator[TestClient]:
    """The app with its answers made ahead (the tests' settings leave them off)."""
    with serving(settings.model_copy(update={"answers_ahead": True})) as test_client:
        yield test_client


def _kept(client: TestClient, tail: str) -> bytes | None:
    """The aircraft's answer kept under its rows' stamps as they are now."""
    app = client.app
    with app.state.session_factory() as session:  # type: ignore[attr-defined]
        return forecast_answers.kept_forecast(
            session,
            tail,
            horizon_days=HORIZON,
            as_of=AS_OF,
            settings=app.state.settings,  # type: ignore[attr-defined]
        )


def _kept_soon(client: TestClient, tail: str) -> bytes | None:
    """_kept once it is there, polled every 50 ms for at most 60 s (the thread polls every
    worker_poll_seconds, 0.05 s in the tests); None if it never is."""
    deadline = time.monotonic() + 60
    while (found := _kept(client, tail)) is None and time.monotonic() < deadline:
        time.sleep(0.05)
    return found


def _fleet(client: TestClient) -> None:
    add_tail(client, "LOW", 40, stress=100.0)
    add_tail(client, "MID", 40, stress=150.0)
    inspect(client, "LOW", START + timedelta(days=10, hours=1), 0.0051)


def _served_as_kept(client: TestClient, kept: dict[str, bytes | None]) -> None:
    """Each tail's forecast served is the one kept for it, and equal to the answer made from
    scratch (nothing kept)."""
    served = {}
    for tail, body in kept.items():
        assert body is not None, f"no answer of {tail} was made ahead"
        answer = client.get(f"/aircraft/{tail}/forecast", params={"horizon_days": HORIZON})
        assert answer.status_code == 200, answer.text
        assert answer.content == body
        served[tail] = answer.json()
    forget_kept_answers()
    for tail, body in served.items():
        assert client.get(f"/aircraft/{tail}/forecast").json() == body


def test_after_an_activation_every_answer_is_made_before_it_is_asked(client: TestClient) -> None:
    _fleet(client)
    retrained(client)
    _served_as_kept(client, {tail: _kept_soon(client, tail) for tail in TAILS})


def test_after_an_ingest_the_tails_answer_is_made_before_it_is_asked(client: TestClient) -> None:
    _fleet(client)
    retrained(client)
    before = _kept_soon(client, "MID")
    later_flights(client, "MID")
    after = _kept_soon(client, "MID")
    assert after is not None and after != before
    _served_as_kept(client, {"MID": after})


def test_with_several_locations_the_aircraft_answer_is_made_ahead(client: TestClient) -> None:
    _fleet(client)
    retrained(client)
    assert client.put(
        "/locations/wing", json={"stress_factor": 1.5, "initial_crack_m": 0.002}
    ).status_code in (200, 201)
    body = {
        "inspection_id": "W1",
        "inspected_at": (START + timedelta(days=10, hours=1)).isoformat(),
        "crack_length_m": 0.003,
        "location": "wing",
    }
    assert client.post("/aircraft/LOW/inspections", json=body).status_code == 201
    for job in client.post("/models/retrain").json()["jobs"].values():
        assert wait_for_job(client, job)["status"] == "succeeded"
    kept = _kept_soon(client, "MID")
    assert kept is not None and b'"governing_location"' in kept
    _served_as_kept(client, {"MID": kept})


def test_a_tail_whose_row_is_missing_is_left_to_its_readers(database_url: str) -> None:
    """A repair drops the tail's row: making answers ahead does not fill it (the fill holds the
    lock requests wait for), and the tail's first forecast then makes it.  No worker and no
    thread of its own here: the calls are this test's."""
    settings = settings_for(database_url).model_copy(update={"run_worker": False})
    with serving(settings) as client:
        _fleet(client)
        assert commands.retrain({}, settings)["status"] == "succeeded"
        app = client.app
        factory = app.state.session_factory  # type: ignore[attr-defined]
        ahead = AnswersAhead(factory, settings, encoded_body, nice=0)
        assert ahead.make_changed() == 2
        assert _kept(client, "LOW") is not None and _kept(client, "MID") is not None
        repair(client, "MID")
        assert ahead.make_changed() == 0  # MID has no row now; LOW's are unchanged
        assert _kept(client, "MID") is None and _kept(client, "LOW") is not None
        with factory() as session:
            assert forecast_service.current_stamp(session, "MID") is None  # not filled
        assert client.get("/aircraft/MID/forecast").status_code == 200
        assert _kept(client, "MID") is not None


def test_the_thread_runs_below_the_request_threads(client: TestClient) -> None:
    ahead = client.app.state.answers_ahead  # type: ignore[attr-defined]
    settings = client.app.state.settings  # type: ignore[attr-defined]
    assert ahead.native_id is not None
    mine = os.getpriority(os.PRIO_PROCESS, 0)
    deadline = time.monotonic() + 60  # it lowers itself once started
    while os.getpriority(os.PRIO_PROCESS, ahead.native_id) == mine and time.monotonic() < deadline:
        time.sleep(0.05)
    wanted = min(19, mine + settings.worker_nice // 2)
    assert os.getpriority(os.PRIO_PROCESS, ahead.native_id) == wanted


def test_an_answer_the_service_refuses_is_not_tried_again_until_its_rows_change(
    database_url: str, caplog: pytest.LogCaptureFixture
) -> None:
    """An as-of date past the sampling budget (a 422 for a request): each tail is tried once,
    logged in a line without a traceback, and the next polls make nothing (it was retried on
    every poll, a traceback each: 317 in 4 minutes, a third of a core)."""
    settings = settings_for(database_url).model_copy(update={"run_worker": False})
    with serving(settings) as client:
        _fleet(client)
        assert commands.retrain({}, settings)["status"] == "succeeded"
        small = settings.model_copy(update={"max_sampling_bytes": 16 * 1024 * 1024})
        lead = budget.max_sampled_flights(small) // 4 + 10  # 4 flights a day: past the budget
        far = small.model_copy(update={"as_of": AS_OF + timedelta(days=lead)})
        factory = client.app.state.session_factory  # type: ignore[attr-defined]
        ahead = AnswersAhead(factory, far, encoded_body, nice=0)
        with caplog.at_level("INFO", logger="fleetpinn.answers_ahead"):
            assert ahead.make_changed() == 2
            assert ahead.make_changed() == 0
            assert ahead.make_changed() == 0
        said = [r for r in caplog.records if r.name == "fleetpinn.answers_ahead"]
        assert len(said) == 2 and all(r.exc_info is None for r in said)
        assert all("FLEETPINN_MAX_SAMPLING_BYTES" in r.getMessage() for r in said)
        later_flights(client, "LOW")  # drops its row; its reader fills a new one
        assert client.get("/aircraft/LOW/forecast").status_code == 200
        assert ahead.make_changed() == 1  # its rows changed: tried again
