"""A fleet set up as a structures engineer sets it up: a catalogue of control points, each
aircraft carrying its own (never `default`), flights, inspections at each location, a retrain.
Every aircraft route, page and client command then answers for the aircraft: every location it
carries, the governing one named, the ones it cannot weigh listed with their reason."""

import json
import re
from datetime import timedelta
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.cli import api, main
from app.local_server import wait_for_job
from app.services.forecasts.crack_history import crack_history
from tests.app.conftest import SQLITE_ONLY_SERVER, START, add_tail, serving, settings_for
from tests.app.snapshots import copied_for_each_test, copy_of, served_settings

WING = {"stress_factor": 1.5, "initial_crack_m": 0.002, "critical_crack_m": 0.04}
KEEL = {"stress_factor": 1.2, "initial_crack_m": 0.002, "critical_crack_m": 0.03}
# a location no tail was ever inspected at: its retrain makes its analysis (the physics)
FIN = {"stress_factor": 1.0, "initial_crack_m": 0.002, "critical_crack_m": 0.05}
# what it checks lies above the storage (tests/app/test_location_models.py has both backends)
pytestmark = SQLITE_ONLY_SERVER

TAILS = {"N1": 100.0, "N2": 150.0, "N3": 120.0}


def _inspection(name: str, tail: str, crack_m: float) -> dict[str, Any]:
    return {
        "inspection_id": f"{tail}-{name}",
        "inspected_at": (START + timedelta(days=10)).isoformat(),
        "crack_length_m": crack_m,
        "location": name,
    }


def _retrain_all(client: TestClient) -> dict[str, dict[str, Any]]:
    accepted = client.post("/models/retrain")
    assert accepted.status_code == 202, accepted.text
    return {name: wait_for_job(client, job) for name, job in accepted.json()["jobs"].items()}


def _store_fleet(client: TestClient) -> None:
    """Three tails carrying wing, keel and fin (not default), inspected at wing and keel."""
    for name, entry in (("wing", WING), ("keel", KEEL), ("fin", FIN)):
        assert client.put(f"/locations/{name}", json=entry).status_code == 201
    for tail, stress in TAILS.items():
        add_tail(client, tail, 40, stress=stress)
        carried = client.put(f"/aircraft/{tail}/locations", json={"locations": ["wing", "keel"]})
        assert carried.status_code == 200, carried.text
    for tail in ("N1", "N2"):
        for name in ("wing", "keel"):
            answer = client.post(
                f"/aircraft/{tail}/inspections", json=_inspection(name, tail, 0.0021)
            )
            assert answer.status_code == 201, answer.text
    jobs = _retrain_all(client)
    assert set(jobs) == {"wing", "keel"}, "only the locations some aircraft carries"
    for name, job in jobs.items():
        assert job["status"] == "succeeded", (name, job["error"])


stored_database, fleet = copied_for_each_test("fleet", _store_fleet)


def _aircraft(client: TestClient, tail: str) -> dict[str, Any]:
    answer = client.get(f"/aircraft/{tail}/forecast")
    assert answer.status_code == 200, answer.text
    body: dict[str, Any] = answer.json()
    return body


def test_every_aircraft_names_the_governing_location_the_ranking_puts_first(
    fleet: TestClient,
) -> None:
    client = fleet
    ranking = client.get("/fleet/ranking", params={"limit": 100}).json()
    first: dict[str, str] = {}
    for item in ranking["items"]:
        first.setdefault(item["tail"], item["location"])
    assert set(first) == set(TAILS)
    for tail in TAILS:
        body = _aircraft(client, tail)
        assert body["governing_location"] == first[tail]
        assert {line["location"] for line in body["locations"]} == {"wing", "keel"}
        # the body is the governing location's full forecast
        full = client.get(f"/aircraft/{tail}/locations/{first[tail]}/forecast").json()
        assert body["location"] == first[tail]
        assert body["prob_critical"] == full["prob_critical"]
        assert body["critical_crack_m"] == full["critical_crack_m"]
        assert body["trajectory"] == full["trajectory"]


def test_a_location_never_inspected_on_the_tail_is_listed_with_its_reason(
    fleet: TestClient,
) -> None:
    notes = {n["location"]: n["reason"] for n in _aircraft(fleet, "N3")["location_notes"]}
    assert set(notes) == {"wing", "keel"}
    assert all("never inspected" in reason for reason in notes.values())
    inspected = _aircraft(fleet, "N1")
    assert "location_notes" not in inspected


def test_a_carried_location_without_a_model_is_listed_with_its_reason(fleet: TestClient) -> None:
    client = fleet
    carried = client.put("/aircraft/N1/locations", json={"locations": ["wing", "keel", "fin"]})
    assert carried.status_code == 200
    body = _aircraft(client, "N1")
    assert body["unassessed_locations"] == ["fin"]
    notes = {n["location"]: n["reason"] for n in body["location_notes"]}
    assert "no active model version" in notes["fin"]
    assert body["governing_location"] in ("wing", "keel")


def test_an_aircraft_whose_locations_have_no_model_is_a_conflict_naming_them(
    fleet: TestClient,
) -> None:
    client = fleet
    assert client.put("/aircraft/N1/locations", json={"locations": ["fin"]}).status_code == 200
    answer = client.get("/aircraft/N1/forecast")
    assert answer.status_code == 409
    assert "fin" in answer.json()["detail"]


def test_the_image_and_the_page_show_every_location(fleet: TestClient) -> None:
    client = fleet
    image = client.get("/aircraft/N2/forecast.svg")
    assert image.status_code == 200, image.text
    assert image.headers["content-type"].startswith("image/svg")
    page = client.get("/pages/aircraft/N2")
    assert page.status_code == 200
    assert "No aircraft is registered" not in page.text
    governing = _aircraft(client, "N2")["governing_location"]
    assert f"governing location: {governing}" in page.text.lower().replace("<b>", "").replace(
        "</b>", ""
    )
    for name in ("wing", "keel"):
        assert f"N2 at {name}: estimated crack and forecast" in page.text
    # each inspection in the page's table says which location it was at
    cells = re.findall(r'<td class="inspection-location">([^<]*)</td>', page.text)
    assert sorted(cells) == ["keel", "wing"]


def test_the_client_forecast_summarises_the_aircraft(
    fleet: TestClient, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    client = fleet
    monkeypatch.setattr(
        api.Api, "call", lambda _self, method, path, **kw: client.request(method, path, **kw)
    )
    assert main(["client", "--url", "http://testserver", "forecast", "N3"]) == 0
    printed = capsys.readouterr().out
    governing = _aircraft(client, "N3")["governing_location"]
    assert f"governing location {governing}" in printed
    assert "never inspected" in printed


def test_a_planned_forecast_is_the_governing_locations(fleet: TestClient) -> None:
    client = fleet
    unplanned = client.get("/aircraft/N2/forecast", params={"horizon_days": 30}).json()
    governing = unplanned["governing_location"]
    planned = {"flights_per_day": 4, "missions": [{"stress_range_mpa": 150.0, "share": 1.0}]}
    answer = client.post("/aircraft/N2/forecast", json={"horizon_days": 30, "planned": planned})
    assert answer.status_code == 200, answer.text
    body = answer.json()
    assert body["location"] == governing and body["planned"] is True
    assert body["critical_crack_m"] == (WING if governing == "wing" else KEEL)["critical_crack_m"]


def test_cancelling_one_of_a_retrains_jobs_cancels_them_all(
    stored_database: str, tmp_path: Path
) -> None:
    with copy_of(stored_database, tmp_path) as url:
        quiet = settings_for(url).model_copy(update={"run_worker": False})
        with serving(quiet) as client:
            accepted = client.post("/models/retrain").json()
            assert set(accepted["jobs"]) == {"wing", "keel"}
            # a second retrain while these are queued gets them back (one queued retrain a
            # location), and a batch job queued beside them is not the retrain's
            again = client.post("/models/retrain").json()
            assert again["jobs"] == accepted["jobs"]
            batch = client.post("/forecasts/batch", json={}).json()["job_id"]
            last = accepted["jobs"]["wing"]
            cancelled = client.post(f"/jobs/{last}/cancel")
            assert cancelled.status_code == 200, cancelled.text
            for job_id in accepted["jobs"].values():
                assert client.get(f"/jobs/{job_id}").json()["status"] == "cancelled"
            assert client.get(f"/jobs/{batch}").json()["status"] == "queued"


def test_the_client_retrain_waits_for_every_location_and_reports_each(
    fleet: TestClient, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    client = fleet
    monkeypatch.setattr(
        api.Api, "call", lambda _self, method, path, **kw: client.request(method, path, **kw)
    )
    assert main(["client", "--url", "http://testserver", "retrain", "--wait", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert sorted(row["location"] for row in rows) == ["keel", "wing"]
    assert all(row["status"] == "succeeded" for row in rows)
    assert main(["client", "--url", "http://testserver", "retrain", "--wait"]) == 0
    table = capsys.readouterr().out
    assert "keel" in table and "wing" in table and "location" in table


def test_the_client_stores_a_files_inspections_where_its_location_column_says(
    fleet: TestClient,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
) -> None:
    client = fleet
    with_pod = {**KEEL, "pod_a50_m": 0.0015, "pod_a90_m": 0.0025}
    assert client.put("/locations/keel", json=with_pod).status_code == 200
    monkeypatch.setattr(
        api.Api, "call", lambda _self, method, path, **kw: client.request(method, path, **kw)
    )
    found = tmp_path / "found.csv"
    found.write_text(
        "tail,inspection_id,inspected_at,crack_length_m,detected,location\n"
        "N3,C1,2024-01-09,0.0022,true,wing\n"
        "N3,C2,2024-01-09,,false,keel\n"
    )
    argv = ["client", "--url", "http://testserver", "inspect", "--file", str(found), "--json"]
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out)["inserted"] == 2
    stored = {i["inspection_id"]: i for i in client.get("/aircraft/N3/inspections").json()}
    assert stored["C1"]["location"] == "wing" and stored["C1"]["crack_length_m"] == 0.0022
    # nothing found, no threshold given: the catalogue's PoD of the keel's method applies
    assert stored["C2"]["location"] == "keel"
    assert (stored["C2"]["pod_a50_m"], stored["C2"]["pod_a90_m"]) == (0.0015, 0.0025)
    one = [
        "client", "--url", "http://testserver", "inspect", "N3", "--id", "C3",
        "--at", "2024-01-10", "--crack-m", "0.0023", "--location", "keel",
    ]  # fmt: skip
    assert main(one) == 0
    capsys.readouterr()
    stored = {i["inspection_id"]: i for i in client.get("/aircraft/N3/inspections").json()}
    assert stored["C3"]["location"] == "keel"
    wrong = tmp_path / "wrong.csv"
    wrong.write_text(
        "tail,inspection_id,inspected_at,crack_length_m,location\nN3,C4,2024-01-10,0.002,keeel\n"
    )
    argv = ["client", "--url", "http://testserver", "inspect", "--file", str(wrong)]
    assert main(argv) == 2
    said = capsys.readouterr().err.strip().splitlines()
    assert len(said) == 1 and "row 1, column location" in said[0] and "keeel" in said[0]
    assert "C4" not in {i["inspection_id"] for i in client.get("/aircraft/N3/inspections").json()}


def test_forecast_batch_out_writes_the_exports_tail_location_rows(
    fleet: TestClient, tmp_path: Path
) -> None:
    from app import commands

    out = tmp_path / "batch.json"
    outcome = commands.forecast_batch(out, settings=served_settings(fleet))
    assert outcome["status"] == "succeeded", outcome
    written = [(row["tail"], row["location"]) for row in json.loads(out.read_text())]
    exported = fleet.get("/forecasts", params={"format": "json"}).json()
    assert written == [(row["tail"], row["location"]) for row in exported]
    assert len(written) == 2 * len(TAILS)
    image = fleet.get("/fleet/ranking.svg")
    assert image.status_code == 200, image.text


def test_a_fleet_carrying_one_of_the_active_locations_ranks_and_batches(
    fleet: TestClient,
) -> None:
    client = fleet
    for tail in TAILS:
        carried = client.put(f"/aircraft/{tail}/locations", json={"locations": ["wing"]})
        assert carried.status_code == 200
    ranking = client.get("/fleet/ranking")
    assert ranking.status_code == 200, ranking.text
    assert {item["location"] for item in ranking.json()["items"]} == {"wing"}
    assert _aircraft(client, "N1")["governing_location"] == "wing"
    batch = client.post("/forecasts/batch")
    assert batch.status_code == 202, batch.text
    assert wait_for_job(client, batch.json()["job_id"])["status"] == "succeeded"


def test_the_fleet_page_counts_aircraft_and_names_each_locations_model(fleet: TestClient) -> None:
    answer = fleet.get("/")
    assert answer.status_code == 200
    page = answer.text
    header = page[page.index('id="fleet-models"') :]
    header = header[: header.index("</p>")]
    assert "3 aircraft, 6 (tail, location) rows" in header
    versions = {v["location"]: v["version"] for v in fleet.get("/models").json()}
    for name in ("keel", "wing"):
        assert f"{name}: v{versions[name]}, a_crit" in header
    card = page[page.index('id="count-all"') :]
    assert "Aircraft" in card[:200] and "<dd>3</dd>" in card[:300]


def test_models_and_jobs_say_which_location_each_version_and_job_is_of(fleet: TestClient) -> None:
    models = fleet.get("/models").json()
    assert sorted(v["location"] for v in models) == ["keel", "wing"]
    one = fleet.get(f"/models/{models[0]['version']}").json()
    assert one["location"] == models[0]["location"]
    page = fleet.get("/pages/models").text
    assert "No active model yet" not in page
    active = page[page.index('id="active-models"') :]
    for v in models:
        assert f"{v['location']} v{v['version']}" in active[: active.index("</p>")]
    table = page[page.index('id="models"') :]
    assert "<th>Location</th>" in table
    assert '<td class="location">wing</td>' in table and '<td class="location">keel</td>' in table


def test_a_crack_past_critical_during_the_recorded_flights_says_when_it_crossed(
    fleet: TestClient,
) -> None:
    """450 MPa at a 2.2 mm a_crit from 2 mm: crossed after ~20 of N2's 40 flights."""
    client = fleet
    tiny = {"stress_factor": 3.0, "initial_crack_m": 0.002, "critical_crack_m": 0.0022}
    assert client.put("/locations/tiny", json=tiny).status_code == 201
    carried = client.put("/aircraft/N2/locations", json={"locations": ["wing", "keel", "tiny"]})
    assert carried.status_code == 200
    for name, job in _retrain_all(client).items():
        assert job["status"] == "succeeded", (name, job["error"])
    body = client.get("/aircraft/N2/locations/tiny/forecast").json()
    assert body["past_critical"] is True and body["crack_length_m"] is None
    since = body["past_critical_since"]
    assert since < body["last_flown_at"]
    history = crack_history(
        client.app.state.session_factory(),  # type: ignore[attr-defined]
        "N2",
        served_settings(client),
        max_points=10_000,
        location="tiny",
    )
    first = next(d for d, c in zip(history.dates, history.crack_m, strict=True) if c >= 0.0022)
    assert since == first.isoformat().replace("+00:00", "Z")
    page = client.get("/pages/aircraft/N2").text
    card = page[page.index('id="crack-last-flight"') :]
    assert "past critical" in card[:300] and "500.00" not in card[:300]


def test_the_fleet_page_names_a_carried_location_without_a_model_and_why(
    fleet: TestClient,
) -> None:
    client = fleet
    assert 'id="unassessed"' not in client.get("/").text  # fin is carried by nobody
    assert client.put("/aircraft/N1/locations", json={"locations": ["wing", "fin"]})
    page = client.get("/").text
    banner = page[page.index('id="unassessed"') :]
    banner = banner[: banner.index("</ul>")]
    assert "Location fin has no forecast" in banner and "no retrain has trained" in banner
    assert "wing" not in banner and "keel" not in banner


def test_a_locations_walker_law_is_the_one_its_retrain_fits(fleet: TestClient) -> None:
    """The fleet's setting is Paris; the keel's entry says Walker, with its own gamma."""
    client = fleet
    walker = {"law": "walker", "paris_c": 1.5e-11, "paris_m": 3.8, "walker_gamma": 0.55}
    assert client.put("/locations/keel", json={**KEEL, "growth_law": walker}).status_code == 200
    jobs = _retrain_all(client)
    assert jobs["keel"]["status"] == "succeeded", jobs["keel"]["error"]
    versions = {v["version"]: v for v in client.get("/models").json()}
    keel = versions[jobs["keel"]["result"]["model_version"]]
    wing = versions[jobs["wing"]["result"]["model_version"]]
    assert keel["metrics"]["growth_law"] == {"name": "walker", "gamma": 0.55}
    assert wing["metrics"]["growth_law"]["name"] == "paris"
    assert client.get("/aircraft/N1/locations/keel/forecast").status_code == 200
