"""A location the tail carries without an active version is named in the aircraft's answer
(`unassessed_locations`), its client output and its page, never silently left out."""

from datetime import timedelta
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.cli import api, main
from tests.app.conftest import START, add_tail, inspect
from tests.app.snapshots import copied_for_each_test
from tests.app.test_location_models import WING, _retrain

KEEL = {"stress_factor": 1.6, "initial_crack_m": 0.002, "critical_crack_m": 0.03}


def _store_default_only(client: TestClient) -> None:
    """Two tails with the default location's model, the only active version."""
    for tail, stress in (("LOW", 100.0), ("HIGH", 150.0)):
        add_tail(client, tail, 40, stress=stress)
    inspect(client, "LOW", START + timedelta(days=10), 0.00501)
    _retrain(client)


stored_database, default_only = copied_for_each_test("default_only", _store_default_only)


def _aircraft(client: TestClient) -> dict[str, Any]:
    answer = client.get("/aircraft/HIGH/forecast")
    assert answer.status_code == 200, answer.text
    body: dict[str, Any] = answer.json()
    return body


def test_a_location_catalogued_after_the_retrain_is_named_until_one_gives_it_a_model(
    default_only: TestClient,
) -> None:
    """The default location alone active: the answer is its forecast plus the names (the memo
    keeps no answer from before the entry); the next retrain's analysis assesses it."""
    client = default_only
    before = client.get("/aircraft/HIGH/forecast")
    assert "unassessed_locations" not in before.json()
    assert client.put("/locations/wing", json=WING).status_code == 201
    body = _aircraft(client)
    assert body["unassessed_locations"] == ["wing"]
    assert "governing_location" not in body and "locations" not in body
    assert body["location_notes"][0]["location"] == "wing"
    assert "no active model version" in body["location_notes"][0]["reason"]
    added = ("unassessed_locations", "location_notes")
    assert {k: v for k, v in body.items() if k not in added} == before.json()
    planned = client.post("/aircraft/HIGH/forecast", json={"horizon_days": 30}).json()
    assert planned["unassessed_locations"] == ["wing"]
    # one location's own answer summarises nothing
    named = client.get("/aircraft/HIGH/locations/default/forecast").json()
    assert "unassessed_locations" not in named
    _retrain(client)
    after = _aircraft(client)
    assert "unassessed_locations" not in after
    assert {line["location"] for line in after["locations"]} == {"default", "wing"}


def test_several_active_locations_name_the_one_without_a_model_beside_their_summary(
    default_only: TestClient,
) -> None:
    client = default_only
    assert client.put("/locations/wing", json=WING).status_code == 201
    _retrain(client)
    first = _aircraft(client)
    assert "unassessed_locations" not in first
    assert client.put("/locations/keel", json=KEEL).status_code == 201
    body = _aircraft(client)  # the memo's answer under the same rows' stamps is not served
    assert body["unassessed_locations"] == ["keel"]
    assert [line["location"] for line in body["locations"]] == [
        line["location"] for line in first["locations"]
    ]
    assert body["governing_location"] == first["governing_location"] != "keel"


def test_the_names_follow_the_tails_carried_locations(default_only: TestClient) -> None:
    client = default_only
    assert client.put("/locations/wing", json=WING).status_code == 201
    assert _aircraft(client)["unassessed_locations"] == ["wing"]
    listed = client.put("/aircraft/HIGH/locations", json={"locations": ["default"]})
    assert listed.status_code == 200
    assert "unassessed_locations" not in _aircraft(client)
    assert client.get("/aircraft/LOW/forecast").json()["unassessed_locations"] == ["wing"]
    assert client.put("/aircraft/HIGH/locations", json={"locations": []}).status_code == 200
    assert _aircraft(client)["unassessed_locations"] == ["wing"]


def test_the_client_and_the_page_show_each_unassessed_location(
    default_only: TestClient, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    client = default_only
    for name, entry in (("wing", WING), ("keel", KEEL)):
        assert client.put(f"/locations/{name}", json=entry).status_code == 201
    # the CLI's requests go to the app under test instead of over a socket
    monkeypatch.setattr(
        api.Api, "call", lambda _self, method, path, **kw: client.request(method, path, **kw)
    )
    assert main(["client", "--url", "http://testserver", "forecast", "HIGH"]) == 0
    lines = capsys.readouterr().out.splitlines()
    for name in ("keel", "wing"):
        assert any(f"location {name}" in line and "no model yet: retrain" in line for line in lines)
    page = client.get("/pages/aircraft/HIGH").text
    banner = page[page.index('id="unassessed"') :]
    assert "location keel, wing." in banner[: banner.index("</p>")]
    _retrain(client)
    assert main(["client", "--url", "http://testserver", "forecast", "HIGH"]) == 0
    assert "no model yet" not in capsys.readouterr().out
    assert 'id="unassessed"' not in client.get("/pages/aircraft/HIGH").text
