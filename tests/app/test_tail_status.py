"""What the numbers cannot say by themselves, said the same way in every output: how old a tail's
data are (stale beyond stale_after_days), and a crack past a_crit as a flag and a date, never
the bound a march holds it at."""

from __future__ import annotations

import io
from collections.abc import Iterator
from datetime import UTC, date, datetime, timedelta
from pathlib import Path

import pandas as pd
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.local_server import wait_for_job
from app.services.forecasts.tail_status import below_critical, data_age, past_critical
from tests.app.conftest import START, add_tail, inspect, serving, settings_in

A_CRIT = 0.05
# 10 days of flights from START (4 a day): the last one on day 9
LAST_FLIGHT_DAY = START.date() + timedelta(days=9)
# FAST (300 MPa) reaches a_crit within a year of flying; years later it is far past it
LATE = START.date() + timedelta(days=3 * 365)


def _time(value: str) -> datetime:
    return datetime.fromisoformat(value.replace("Z", "+00:00"))


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """FAST (near a_crit within a year), SLOW (inspected on day 5); physics model."""
    settings = settings_in(Path(tmp_path_factory.mktemp("status")))
    with serving(settings) as client:
        add_tail(client, "FAST", 40, stress=300.0)
        add_tail(client, "SLOW", 40, stress=100.0)
        inspect(client, "SLOW", START + timedelta(days=5), 0.00502)
        job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
        assert job["status"] == "succeeded", job["error"]
        yield client


def test_data_age_and_stale_in_forecast_ranking_and_export(fleet: TestClient) -> None:
    as_of = START.date() + timedelta(days=100)
    params = {"as_of": as_of.isoformat(), "horizon_days": 30}
    body = fleet.get("/aircraft/SLOW/forecast", params=params).json()
    age = body["data_age"]
    assert age["days_since_last_flight"] == (as_of - LAST_FLIGHT_DAY).days == 91
    assert age["days_since_last_inspection"] == 95
    assert _time(age["last_inspected_at"]) == START + timedelta(days=5)
    assert age["stale"] is True and body["stale_after_days"] == 60

    ranking = fleet.get("/fleet/ranking", params=params).json()
    by_tail = {item["tail"]: item for item in ranking["items"]}
    assert by_tail["SLOW"]["data_age"] == age
    assert by_tail["FAST"]["data_age"]["days_since_last_inspection"] is None
    assert by_tail["FAST"]["data_age"]["stale"] is True

    fresh = {"as_of": (LAST_FLIGHT_DAY + timedelta(days=60)).isoformat(), "horizon_days": 30}
    item = fleet.get("/fleet/ranking", params=fresh).json()["items"][0]
    assert (item["data_age"]["days_since_last_flight"], item["data_age"]["stale"]) == (60, False)

    export = fleet.get("/forecasts", params={**params, "format": "csv"})
    rows = pd.read_csv(io.StringIO(export.text)).set_index("tail")
    assert rows.loc["SLOW", "days_since_last_flight"] == 91
    assert rows.loc["SLOW", "days_since_last_inspection"] == 95
    assert bool(rows.loc["SLOW", "stale"]) is True
    assert pd.isna(rows.loc["FAST", "days_since_last_inspection"])


def test_a_crack_past_critical_is_a_flag_and_a_date_never_a_length(fleet: TestClient) -> None:
    params = {"as_of": LATE.isoformat(), "horizon_days": 365}
    forecast = fleet.get("/aircraft/FAST/forecast", params=params).json()
    assert forecast["past_critical"] is True
    since = forecast["past_critical_since"]
    assert since is not None and since == forecast["critical_date_quantiles"]["p50"]
    assert _time(since).date() < LATE
    today = forecast["crack_as_of"]
    assert today["crack_length_m"] is None and today["p50"] is None
    assert forecast["crack_at_horizon"]["p50"] is None

    ranking = fleet.get("/fleet/ranking", params=params).json()
    fast = next(i for i in ranking["items"] if i["tail"] == "FAST")
    assert (fast["past_critical"], fast["past_critical_since"]) == (True, since)
    assert fast["crack_as_of_band"] == {"p05": None, "p50": None, "p95": None}
    slow = next(i for i in ranking["items"] if i["tail"] == "SLOW")
    assert (slow["past_critical"], slow["past_critical_since"]) == (False, None)
    assert 0 < slow["crack_as_of_band"]["p50"] < A_CRIT

    for export_format in ("csv", "json"):
        export = fleet.get("/forecasts", params={**params, "format": export_format})
        frame = (
            pd.read_csv(io.StringIO(export.text))
            if export_format == "csv"
            else pd.DataFrame(export.json())
        ).set_index("tail")
        assert bool(frame.loc["FAST", "past_critical"]) is True
        assert frame.loc["FAST", "past_critical_since"] == since
        cracks = frame[[c for c in frame.columns if c.startswith("crack_") and c.endswith("_m")]]
        # measured at its last flight below a_crit; today and at the horizon past it: missing,
        # where the bound a march holds cracks at (0.5 m) stood
        assert 0 < frame.loc["FAST", "crack_last_flight_m"] < A_CRIT
        assert cracks.loc["FAST"].drop("crack_last_flight_m").isna().all()
        assert (cracks.stack().dropna() < A_CRIT).all()


def test_tail_status_rules() -> None:
    flown = datetime(2024, 1, 10, 18, tzinfo=UTC)
    age = data_age(flown, None, date(2024, 3, 10), stale_after_days=60)
    assert (age.days_since_last_flight, age.days_since_last_inspection, age.stale) == (
        60,
        None,
        False,
    )
    assert data_age(flown, flown, date(2024, 3, 11), stale_after_days=60).stale
    assert data_age(flown, flown, date(2024, 1, 1), stale_after_days=60).days_since_last_flight == 0
    with pytest.raises(ValueError, match="stale_after_days"):
        data_age(flown, None, date(2024, 3, 10), stale_after_days=0)
    origin = datetime(2024, 1, 1, tzinfo=UTC)
    reached = datetime(2024, 6, 1, tzinfo=UTC)
    assert past_critical(0.049, 0.05, None, origin).past_critical is False
    assert past_critical(0.5, 0.05, reached, origin).past_critical_since == reached
    assert past_critical(None, 0.05, None, origin).past_critical_since == origin
    assert [below_critical(v, 0.05) for v in (0.01, 0.05, 0.5, None)] == [0.01, None, None, None]


def test_the_setting_moves_the_stale_bound(tmp_path: Path) -> None:
    settings = Settings(database_url=f"sqlite:///{tmp_path / 'x.db'}", stale_after_days=120)
    assert settings.stale_after_days == 120
    with pytest.raises(ValueError, match="stale_after_days"):
        Settings(database_url=f"sqlite:///{tmp_path / 'x.db'}", stale_after_days=0)
