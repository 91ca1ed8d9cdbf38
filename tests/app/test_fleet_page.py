"""The fleet page at a glance: stale data in a banner, past-critical tails as a flag and a date,
search by tail, filters whose counts agree with the rows they show, `?as_of=` on the pages, and
a flagged inspection marked on the tail's chart."""

from __future__ import annotations

import re
from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from app.local_server import wait_for_job
from app.web import views
from tests.app.conftest import START, add_tail, inspect, serving, settings_in

LAST_FLIGHT_DAY = START.date() + timedelta(days=9)
STALE = START.date() + timedelta(days=100)  # 91 days after the last flight
FRESH = LAST_FLIGHT_DAY + timedelta(days=10)
LATE = START.date() + timedelta(days=3 * 365)  # FAST far past a_crit


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """FAST (reaches a_crit within a year), SLOW (a measurement far from its forecast: flagged),
    SLOWER; physics model."""
    settings = settings_in(Path(tmp_path_factory.mktemp("fleet_page")))
    with serving(settings) as client:
        add_tail(client, "FAST", 40, stress=300.0)
        add_tail(client, "SLOW", 40, stress=100.0)
        add_tail(client, "SLOWER", 40, stress=90.0)
        inspect(client, "SLOWER", START + timedelta(days=5), 0.00501)
        job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
        assert job["status"] == "succeeded", job["error"]
        surprising = {
            "inspection_id": "ODD",
            "inspected_at": (START + timedelta(days=8)).isoformat(),
            "crack_length_m": 0.02,
        }
        answer = client.post("/aircraft/SLOW/inspections", json=surprising).json()
        assert answer["assessments"][0]["flagged"] is True
        yield client


def _tails(html: str) -> list[str]:
    return re.findall(r'<tr data-tail="([^"]+)"', html)


def _count(html: str, name: str) -> int:
    found = re.search(rf'id="count-{name}"><dt>.*?</dt><dd>(\d+)</dd>', html, re.S)
    assert found, name
    return int(found.group(1))


def test_the_banner_says_how_many_tails_are_stale(fleet: TestClient) -> None:
    page = fleet.get("/", params={"as_of": STALE.isoformat()}).text
    banner = re.search(r'<p class="banner warn" id="stale-banner".*?</p>', page, re.S)
    assert banner, "no stale banner"
    text = " ".join(re.sub("<[^>]+>", "", banner.group(0)).split())
    assert text.startswith("3 of 3 tails have stale data")
    assert "more than 60 days before " + STALE.isoformat() in text and "oldest 91 days" in text
    assert re.search(r'<span id="as-of">' + STALE.isoformat(), page)  # ?as_of= is obeyed
    assert 'class="num col-age" data-value="91"' in page
    fresh = fleet.get("/", params={"as_of": FRESH.isoformat()}).text
    assert "stale-banner" not in fresh
    assert _count(fresh, "stale") == 0


def test_search_by_tail(fleet: TestClient) -> None:
    assert _tails(fleet.get("/", params={"q": " fa "}).text) == ["FAST"]
    assert sorted(_tails(fleet.get("/", params={"q": "slow"}).text)) == ["SLOW", "SLOWER"]
    nothing = fleet.get("/", params={"q": "N999"}).text
    assert _tails(nothing) == [] and 'id="no-rows"' in nothing


@pytest.mark.parametrize("as_of", [STALE, LATE])
def test_each_filter_shows_as_many_rows_as_its_count(fleet: TestClient, as_of: object) -> None:
    everything = fleet.get("/", params={"as_of": str(as_of)}).text
    for show in views.SHOWS:
        page = fleet.get("/", params={"as_of": str(as_of), "show": show}).text
        assert len(_tails(page)) == _count(everything, show) == _count(page, show), show
    assert _count(everything, "all") == 3
    flagged = fleet.get("/", params={"as_of": str(as_of), "show": "flagged"}).text
    assert _tails(flagged) == ["SLOW"]
    # overdue tails are due too: the "due" count never reads below the overdue one
    assert _count(everything, "due") >= _count(everything, "overdue")


def test_past_critical_reads_as_a_flag_and_a_date(fleet: TestClient) -> None:
    ranking = fleet.get("/fleet/ranking", params={"as_of": LATE.isoformat()}).json()
    fast = next(i for i in ranking["items"] if i["tail"] == "FAST")
    assert fast["past_critical"] is True
    since = fast["past_critical_since"][:10]
    page = fleet.get("/", params={"as_of": LATE.isoformat(), "show": "past-critical"}).text
    assert _tails(page) == ["FAST"]
    cell = re.search(r'<td class="num col-crack" data-value="past-critical">(.*?)</td>', page, re.S)
    assert cell, "no past-critical cell"
    text = " ".join(re.sub("<[^>]+>", "", cell.group(1)).split())
    assert text == f"past critical since {since}"
    assert "&gt; a_crit" not in page and "500.00" not in page

    tail_page = fleet.get("/pages/aircraft/FAST", params={"as_of": LATE.isoformat()}).text
    assert 'id="past-critical"' in tail_page
    assert f'<span id="past-critical-since">{since}</span>' in tail_page
    assert f'<span id="as-of">{LATE.isoformat()}</span>' in tail_page


def test_a_flagged_inspection_is_marked_on_the_chart(fleet: TestClient) -> None:
    page = fleet.get("/pages/aircraft/SLOW").text
    assert 'id="inspections-flagged"' in page
    z = fleet.get("/aircraft/SLOW/inspections/ODD").json()["forecast_z"]
    assert f"flagged z={z:+.1f}" in page
    assert f"flagged: z = {z:.1f} against the estimate of" in page
    # its band's edges are drawn, so a thin band stays visible
    assert 'id="band-p05"' in page and 'id="band-p95"' in page
    unflagged = fleet.get("/pages/aircraft/SLOWER").text
    assert 'id="inspections-flagged"' not in unflagged
