"""What an airline's engineer reads where the fleet's one active location is their own (never
`default`) and another carried location has only a stored candidate: the ranking, the export
and the client name the location; a refused or held-back candidate is said to be one, not
"train one"; /ready names each location's active version; an inspection sent without a location names the location it was taken to be at;
a band past a_crit at the last flight reads "> a_crit", never a millimetre value past it."""

from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.cli import api, main
from app.local_server import wait_for_job
from tests.app.conftest import SQLITE_ONLY_SERVER, START, add_tail
from tests.app.snapshots import copied_for_each_test

WING = {"stress_factor": 1.5, "initial_crack_m": 0.002, "critical_crack_m": 0.04}
LUG = {"stress_factor": 1.2, "initial_crack_m": 0.002, "critical_crack_m": 0.03}
TAILS = {"N1": 100.0, "N2": 150.0, "N3": 120.0}
pytestmark = SQLITE_ONLY_SERVER


def _retrain(client: TestClient, **body: Any) -> dict[str, dict[str, Any]]:
    accepted = client.post("/models/retrain", json=body)
    assert accepted.status_code == 202, accepted.text
    jobs = {name: wait_for_job(client, job) for name, job in accepted.json()["jobs"].items()}
    for name, job in jobs.items():
        assert job["status"] == "succeeded", (name, job["error"])
    return jobs


def _store_fleet(client: TestClient) -> None:
    """Three tails carrying wing and lug (not default), inspected at wing; wing's model active,
    lug's only a candidate (its retrain asked not to activate)."""
    assert client.put("/locations/wing", json=WING).status_code == 201
    for tail, stress in TAILS.items():
        add_tail(client, tail, 40, stress=stress)
        carried = client.put(f"/aircraft/{tail}/locations", json={"locations": ["wing"]})
        assert carried.status_code == 200, carried.text
    for tail in ("N1", "N2"):
        finding = {
            "inspection_id": f"{tail}-wing",
            "inspected_at": START.replace(day=11).isoformat(),
            "crack_length_m": 0.0021,
            "location": "wing",
        }
        assert client.post(f"/aircraft/{tail}/inspections", json=finding).status_code == 201
    _retrain(client)
    assert client.put("/locations/lug", json=LUG).status_code == 201
    for tail in TAILS:
        carried = client.put(f"/aircraft/{tail}/locations", json={"locations": ["wing", "lug"]})
        assert carried.status_code == 200, carried.text
    _retrain(client, activate=False)


stored_database, fleet = copied_for_each_test("fleet", _store_fleet)


def _active(client: TestClient) -> dict[str, int]:
    return {
        v["location"]: v["version"] for v in client.get("/models").json() if v["status"] == "active"
    }


def test_the_ranking_and_the_export_name_the_one_active_location(
    fleet: TestClient, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    client = fleet
    assert set(_active(client)) == {"wing"}
    ranking = client.get("/fleet/ranking").json()
    assert [item["location"] for item in ranking["items"]] == ["wing"] * len(TAILS)
    assert {item["model_version"] for item in ranking["items"]} == {_active(client)["wing"]}
    assert {item["critical_crack_m"] for item in ranking["items"]} == {WING["critical_crack_m"]}
    exported = client.get("/forecasts", params={"format": "json"}).json()
    assert [row["location"] for row in exported] == ["wing"] * len(TAILS)
    monkeypatch.setattr(
        api.Api, "call", lambda _self, method, path, **kw: client.request(method, path, **kw)
    )
    assert main(["client", "--url", "http://testserver", "ranking", "--csv"]) == 0
    header, *rows = capsys.readouterr().out.splitlines()
    assert header.split(",")[2] == "location"
    assert [row.split(",")[2] for row in rows] == ["wing"] * len(TAILS)


def test_ready_names_the_active_version_of_each_location(fleet: TestClient) -> None:
    """The default location has none, but wing's serves: /ready says which, not only null."""
    ready = fleet.get("/ready").json()
    assert ready["model_version"] is None
    assert ready["model_versions"] == _active(fleet) == {"wing": ready["model_versions"]["wing"]}


def test_a_location_with_only_a_candidate_says_so_not_train_one(fleet: TestClient) -> None:
    client = fleet
    candidate = max(v["version"] for v in client.get("/models").json() if v["location"] == "lug")
    answer = client.get("/aircraft/N1/locations/lug/forecast")
    assert answer.status_code == 409
    detail = answer.json()["detail"]
    assert f"its latest, v{candidate}, is candidate" in detail, detail
    assert f"POST /models/{candidate}/activate" in detail and "train one" not in detail


def test_an_inspection_without_a_location_names_the_one_it_was_taken_to_be_at(
    fleet: TestClient,
) -> None:
    finding = {"inspection_id": "X1", "inspected_at": START.replace(day=12).isoformat()}
    answer = fleet.post("/aircraft/N1/inspections", json={**finding, "crack_length_m": 0.0021})
    assert answer.status_code == 422
    body = answer.json()
    assert body["column"] == "location"
    assert "does not carry location 'default'" in body["reason"], body["reason"]
    assert "names no location" in body["reason"]
    assert fleet.get("/aircraft/N1/inspections/X1").status_code == 404


def test_a_band_past_a_crit_at_the_last_flight_reads_past_a_crit(
    fleet: TestClient, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A never-inspected location's analysis has a wide band; its a_crit is then put between
    the point crack at the last flight and that band's p95."""
    client = fleet
    edge = {**WING, "critical_crack_m": 0.04}
    assert client.put("/locations/edge", json=edge).status_code == 201
    assert client.put("/aircraft/N3/locations", json={"locations": ["edge"]}).status_code == 200
    _retrain(client)
    before = client.get("/aircraft/N3/forecast").json()
    point, p95 = before["crack_length_m"], before["crack_length_band"]["p95"]
    assert p95 > point * 1.001, (point, p95)
    edge["critical_crack_m"] = (point + p95) / 2
    assert client.put("/locations/edge", json=edge).status_code == 200
    _retrain(client)
    body = client.get("/aircraft/N3/forecast").json()
    assert body["location"] == "edge" and body["critical_crack_m"] == edge["critical_crack_m"]
    assert body["crack_length_m"] < body["critical_crack_m"]
    assert body["crack_length_band"]["p95"] is None  # the API's: past a_crit
    page = client.get("/pages/aircraft/N3").text
    card = page[page.index('id="crack-last-flight"') :]
    card = card[: card.index("</div>")]
    critical_mm = f"{body['critical_crack_m'] * 1000:.2f}"
    assert f"beyond critical (&gt; {critical_mm} mm)" in card, card
    assert f"{body['critical_crack_m'] * 10_000:.2f}" not in card  # no 10 a_crit in mm
    monkeypatch.setattr(
        api.Api, "call", lambda _self, method, path, **kw: client.request(method, path, **kw)
    )
    assert main(["client", "--url", "http://testserver", "forecast", "N3"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "crack at last flight" in x)
    assert f"beyond critical (> {critical_mm} mm)" in line and "–—" not in line, line


def _printed(
    client: TestClient,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    body: dict[str, Any],
    *argv: str,
) -> str:
    """What `fleetpinn client ARGV` prints for this (served, then edited) answer."""
    monkeypatch.setattr(api.Api, "json", lambda _self, method, path, **kw: body)
    assert main(["client", "--url", "http://testserver", *argv]) == 0
    return capsys.readouterr().out


def test_the_client_says_beyond_the_horizon_not_a_dash(
    fleet: TestClient, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A p50 critical date past the horizon (P(critical) < 50 %) with a p05 inside it, and no
    inspect-by: the words the pages use."""
    body = fleet.get("/aircraft/N1/forecast").json()
    body["critical_date_quantiles"] = {"p05": "2024-03-01T00:00:00Z", "p50": None, "p95": None}
    printed = _printed(fleet, monkeypatch, capsys, body, "forecast", "N1")
    line = next(x for x in printed.splitlines() if "critical date p50" in x)
    assert "beyond the horizon (2024-03-01–later)" in line, line
    ranking = fleet.get("/fleet/ranking").json()
    ranking["items"][0]["critical_date_quantiles"]["p50"] = None
    ranking["items"][0]["inspect_by"] = None
    printed = _printed(fleet, monkeypatch, capsys, ranking, "ranking")
    row = next(x for x in printed.splitlines() if f" {ranking['items'][0]['tail']} " in x)
    assert "beyond the horizon" in row and "not due" in row, row


def test_the_client_ranking_title_names_each_locations_model(
    fleet: TestClient, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    ranking = fleet.get("/fleet/ranking").json()
    printed = _printed(fleet, monkeypatch, capsys, ranking, "ranking")
    title = printed.splitlines()[0]
    assert f"(tail, location) rows by risk, models wing v{_active(fleet)['wing']}," in title


def test_the_fleet_pages_likely_card_counts_aircraft_as_the_other_cards_do(
    fleet: TestClient,
) -> None:
    """N2 carries two locations whose a_crit its crack passed: two rows at P(critical) 1, one
    aircraft."""
    client = fleet
    tiny = {"stress_factor": 3.0, "initial_crack_m": 0.002, "critical_crack_m": 0.0022}
    for name in ("tiny-a", "tiny-b"):
        assert client.put(f"/locations/{name}", json=tiny).status_code == 201
    carried = client.put("/aircraft/N2/locations", json={"locations": ["tiny-a", "tiny-b"]})
    assert carried.status_code == 200
    _retrain(client)
    items = client.get("/fleet/ranking", params={"limit": 100}).json()["items"]
    likely_rows = [i for i in items if i["prob_critical"] >= 0.5]
    assert [i["tail"] for i in likely_rows].count("N2") == 2, likely_rows
    page = client.get("/").text
    card = page[page.index("P(critical) ≥ 50 %") :]
    shown = int(card[card.index("<dd>") + 4 : card.index("</dd>")])
    assert shown == len({i["tail"] for i in likely_rows}) < len(likely_rows)


def test_the_catalogue_page_says_how_many_aircraft_carry_each_location(
    fleet: TestClient,
) -> None:
    """Every tail carries wing and lug: the default location, whose stored description says
    every aircraft has it, is carried by none; once N3 lists none, it carries them all."""
    client = fleet

    def carried() -> dict[str, str]:
        page = client.get("/pages/locations").text
        found = {}
        for name in ("default", "wing", "lug"):
            row = page[page.index(f'id="row-{name}"') :]
            row = row[row.index('class="num carried"') :]
            found[name] = row[row.index('data-value="') + 12 : row.index('">')]
        return found

    assert carried() == {"default": "0", "wing": "3", "lug": "3"}
    row = client.get("/pages/locations").text.split('id="row-default"')[1]
    assert ">none</span></td>" in row[: row.index("</tr>")]
    assert client.put("/aircraft/N3/locations", json={"locations": []}).status_code == 200
    assert carried() == {"default": "1", "wing": "3", "lug": "3"}


def test_an_inspection_at_an_own_location_is_compared_with_that_locations_forecast(
    fleet: TestClient,
) -> None:
    """A digit slip at wing (21 mm for 2.1 mm) is flagged against wing's own model; the
    reading as it was is not."""
    at = START.replace(day=20).isoformat()
    slip = {"inspection_id": "S1", "inspected_at": at, "crack_length_m": 0.021, "location": "wing"}
    right = {**slip, "inspection_id": "S2", "crack_length_m": 0.0021}
    answer = fleet.post("/aircraft/N1/inspections", json=[slip, right])
    assert answer.status_code == 201, answer.text
    slipped, kept = answer.json()["assessments"]
    assert slipped["forecast_crack_m"] == pytest.approx(0.0021, rel=0.1), slipped
    assert slipped["flagged"] is True and slipped["forecast_z"] > 3
    assert kept["flagged"] is False and abs(kept["forecast_z"]) < 3
    stored = {i["inspection_id"]: i for i in fleet.get("/aircraft/N1/inspections").json()}
    assert stored["S1"]["flagged"] is True


def test_a_file_row_the_server_refuses_is_named_by_its_row_in_the_file(
    fleet: TestClient,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
) -> None:
    """N1's row is fine; N2's third row names no location (the default one, which N2 does
    not carry): the error names the file's row 3, not the request's 'body row 2', and says
    N1's inspection is stored already."""
    client = fleet
    at = START.replace(day=21).strftime("%Y-%m-%dT%H:%M:%SZ")
    path = tmp_path / "ours.csv"
    path.write_text(
        "tail,inspection_id,inspected_at,crack_length_m,location\n"
        f"N2,A1,{at},0.0021,wing\n"
        f"N1,A2,{at},0.0021,wing\n"
        f"N2,A3,{at},0.0021,\n"
    )
    served = api.Api.call

    def call(self: api.Api, method: str, route: str, **kw: Any) -> Any:
        own, self.http = self.http, client  # the Api's own status handling, in process
        try:
            return served(self, method, route, **kw)
        finally:
            self.http = own

    monkeypatch.setattr(api.Api, "call", call)
    assert main(["client", "--url", "http://testserver", "inspect", "--file", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "ours.csv row 3, column location" in err and "body row" not in err, err
    assert "stored already: the inspections of N1" in err, err
    assert client.get("/aircraft/N1/inspections/A2").status_code == 200
    assert client.get("/aircraft/N2/inspections/A1").status_code == 404
