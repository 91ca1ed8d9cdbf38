"""A crack quantile at or past a_crit, as a user reads it: the march holds such a path at a
fixed bound (a multiple of a_crit), so the tail's page and the client say "beyond critical
(> a_crit mm)" (app.web.format.beyond_critical) and never print that bound as a length; the
JSON reports it as null.

The fleet is a location's analysis version (a location nobody inspected: the physics with the
fleet spread's prior, whose bands are wide), 450 MPa at the crack from 2 mm: its p50 after the
40 recorded flights is 2.6 mm, its p95 past a 3 mm a_crit."""

import html
import re

import pytest
from fastapi.testclient import TestClient

from app.cli import api, main
from app.local_server import wait_for_job
from app.web import format as fmt
from tests.app.conftest import SQLITE_ONLY_SERVER, add_tail
from tests.app.snapshots import copied_for_each_test

# what it checks lies above the storage
pytestmark = SQLITE_ONLY_SERVER

NARROW = {"stress_factor": 3.0, "initial_crack_m": 0.002, "critical_crack_m": 0.003}


def _retrain(client: TestClient) -> None:
    accepted = client.post("/models/retrain")
    assert accepted.status_code == 202, accepted.text
    for name, job in accepted.json()["jobs"].items():
        assert wait_for_job(client, job)["status"] == "succeeded", name


def _store_fleet(client: TestClient) -> None:
    """One tail, 40 flights at 150 MPa, carrying only `narrow`, never inspected; retrained."""
    assert client.put("/locations/narrow", json=NARROW).status_code == 201
    add_tail(client, "N2", 40, stress=150.0)
    carried = client.put("/aircraft/N2/locations", json={"locations": ["narrow"]})
    assert carried.status_code == 200, carried.text
    _retrain(client)


stored_database, fleet = copied_for_each_test("fleet", _store_fleet)


def _card(page: str, card_id: str) -> str:
    """The text of one summary card of a tail's page, tags stripped, spaces collapsed."""
    card = page[page.index(f'id="{card_id}"') :]
    card = card[: card.index("</div>")]
    return " ".join(html.unescape(re.sub(r"<[^>]+>", " ", card.split(">", 1)[1])).split())


def test_the_band_at_the_last_flight_names_a_crit_where_its_p95_is_past_it(
    fleet: TestClient,
) -> None:
    body = fleet.get("/aircraft/N2/forecast").json()
    band = body["crack_length_band"]
    assert body["crack_length_m"] < 0.003 and band["p95"] is None, body  # the case it is about
    page = fleet.get("/pages/aircraft/N2").text
    card = _card(page, "crack-last-flight")
    assert card == (
        f"Crack at last flight {fmt.mm(body['crack_length_m'])} mm "
        f"p05–p95 {fmt.mm(band['p05'])} mm – beyond critical (> 3.00 mm)"
    )
    summary = page[page.index('id="summary"') : page.index('id="forecast-chart"')]
    shown_mm = [float(n) for n in re.findall(r"([\d,]+\.\d\d)(?:</span>)? mm", summary)]
    assert shown_mm and max(shown_mm) <= 3.00, shown_mm  # no length past a_crit anywhere


def test_the_client_says_beyond_critical_as_the_page_does(
    fleet: TestClient, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(
        api.Api, "call", lambda _self, method, path, **kw: fleet.request(method, path, **kw)
    )
    assert main(["client", "--url", "http://testserver", "forecast", "N2"]) == 0
    printed = " ".join(capsys.readouterr().out.replace("│", " ").split())
    body = fleet.get("/aircraft/N2/forecast").json()
    last = f"{fmt.mm(body['crack_length_m'])} ({fmt.mm(body['crack_length_band']['p05'])} –"
    assert f"crack at last flight, mm (p05–p95) {last} beyond critical (> 3.00 mm))" in printed
    assert "—" not in printed.split("crack at last flight")[1].split("crack on")[0]


def test_a_p50_past_a_crit_at_the_horizon_reads_in_words_with_a_crit(fleet: TestClient) -> None:
    """A location whose crack passes a_crit during the recorded flights: the horizon's card
    reads "beyond critical (> 2.20 mm)", no length and no unit after it."""
    tiny = {**NARROW, "critical_crack_m": 0.0022}
    assert fleet.put("/locations/narrow", json=tiny).status_code == 200
    _retrain(fleet)
    page = fleet.get("/pages/aircraft/N2").text
    assert _card(page, "crack-at-horizon").endswith("beyond critical (> 2.20 mm)")
