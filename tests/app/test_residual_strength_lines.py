"""The residual strength where a user reads a tail: each location's line of the aircraft's
answer and the tail's page carry it (p50, its margin over the limit stress, the criterion)
where the location gives a limit stress; a location without one answers as before."""

from __future__ import annotations

import html
import math
import re
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import timedelta
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from app.local_server import wait_for_job
from app.web import format as fmt
from tests.app.conftest import START, add_tail, inspect, serving, settings_in
from tests.app.snapshots import copied_for_each_test
from tests.app.test_location_crack_cases import PANEL

# a one-location answer's keys before crack cases (issue 41): a location of today's
# catalogue (constant F, typed a_crit) answers with these and no others
KEYS_BEFORE = {
    "tail", "model_version", "origin", "last_flown_at", "as_of", "flights_flown",
    "crack_length_m", "crack_length_band", "crack_as_of", "crack_at_horizon",
    "critical_crack_m", "flights_per_day", "horizon_days", "samples", "model_uncertainty",
    "planned", "trajectory", "flights_to_critical", "critical_date", "prob_critical",
    "flights_to_critical_quantiles", "critical_date_quantiles", "inspect_by", "inspect_rule",
    "overdue", "past_critical", "past_critical_since", "data_age", "stale_after_days", "growth",
}  # fmt: skip
# and those present only where they say something, as before
OPTIONAL_BEFORE = {
    "governing_location", "locations", "location", "unassessed_locations", "location_notes",
    "as_of_note",
}  # fmt: skip
LINE_KEYS_BEFORE = {
    "location", "model_version", "crack_as_of_m", "critical_crack_m", "prob_critical",
    "inspect_by", "overdue", "past_critical",
}  # fmt: skip


def _store(client: TestClient) -> None:
    """Two tails at constant stress, the default location (constant F) and the panel (a
    Feddersen centre crack with a limit stress of 150 MPa), each inspected on LOW, retrained."""
    for tail, stress in (("LOW", 100.0), ("HIGH", 150.0)):
        add_tail(client, tail, 40, stress=stress)
    inspect(client, "LOW", START + timedelta(days=10), 0.00501)
    assert client.put("/locations/panel", json=PANEL).status_code == 201
    at_panel = {
        "inspection_id": "P1",
        "inspected_at": (START + timedelta(days=10)).isoformat(),
        "crack_length_m": 0.00201,
        "location": "panel",
    }
    assert client.post("/aircraft/LOW/inspections", json=at_panel).status_code == 201
    for name, job in client.post("/models/retrain").json()["jobs"].items():
        assert wait_for_job(client, job)["status"] == "succeeded", name


stored_database, fleet = copied_for_each_test("fleet", _store)


def _by_hand(crack_m: float) -> tuple[float, str]:
    """The panel's residual strength at a crack: Feddersen's secant at K = 80 MPa sqrt(m),
    net section 345 (W - 2a) / W in a 0.3 m panel, the smaller governs."""
    by_fracture = 80.0 / math.sqrt(math.pi * crack_m / math.cos(math.pi * crack_m / 0.3))
    by_yield = 345.0 * (0.3 - 2 * crack_m) / 0.3
    if by_fracture < by_yield:
        return by_fracture, "fracture"
    return by_yield, "net_section_yield"


def test_each_line_with_a_limit_stress_carries_its_residual_strength(fleet: TestClient) -> None:
    body = fleet.get("/aircraft/HIGH/forecast").json()
    lines = {line["location"]: line for line in body["locations"]}
    assert set(lines) == {"default", "panel"}
    # the default location (constant F, typed a_crit): its line and the body as before
    assert set(lines["default"]) == LINE_KEYS_BEFORE
    assert "residual_strength" not in body
    assert set(body) - OPTIONAL_BEFORE == KEYS_BEFORE
    panel = fleet.get("/aircraft/HIGH/locations/panel/forecast").json()
    strength = lines["panel"]["residual_strength"]
    assert set(lines["panel"]) == LINE_KEYS_BEFORE | {"residual_strength"}
    crack = panel["crack_as_of"]["p50"]
    assert lines["panel"]["crack_as_of_m"] == pytest.approx(crack, rel=1e-12)
    want, criterion = _by_hand(crack)
    assert strength["residual_strength_mpa"] == pytest.approx(want, rel=1e-9)
    assert strength["criterion"] == criterion
    assert strength["margin"] == pytest.approx(want / 150.0 - 1, rel=1e-9)
    assert strength["limit_stress_mpa"] == 150.0
    # the same figures as the location's own forecast reports at its p50
    full = panel["residual_strength"]["p50"]
    assert (strength["residual_strength_mpa"], strength["margin"]) == (
        full["residual_strength_mpa"],
        full["margin"],
    )


def test_a_constant_factor_location_answers_exactly_the_keys_it_did(fleet: TestClient) -> None:
    """Issue 41's goal: no `residual_strength: null` added where none can be computed (the
    aircraft's optional fields are absent where they say nothing, docs/api.md)."""
    plain = fleet.get("/aircraft/HIGH/locations/default/forecast")
    assert plain.status_code == 200
    assert set(plain.json()) - OPTIONAL_BEFORE == KEYS_BEFORE
    assert "residual_strength" not in plain.text


def test_the_tail_page_shows_each_locations_residual_strength(fleet: TestClient) -> None:
    lines = {
        line["location"]: line for line in fleet.get("/aircraft/HIGH/forecast").json()["locations"]
    }
    page = fleet.get("/pages/aircraft/HIGH").text
    # the body is the default location's, which has no limit stress: no card
    assert 'id="residual-strength"' not in page
    panel = page[page.index('id="location-panel"') :]
    strength = lines["panel"]["residual_strength"]
    shown = re.search(r'class="residual-strength" data-value="([^"]+)"[^>]*>([^<]+)<', panel)
    assert shown is not None
    assert float(shown.group(1)) == pytest.approx(strength["residual_strength_mpa"], rel=1e-12)
    assert html.unescape(shown.group(2)) == fmt.strength_words(**strength)
    default = page[: page.index('id="location-panel"')]
    assert "residual-strength" not in default


def test_a_tail_shown_at_a_location_with_a_limit_stress_has_the_card(fleet: TestClient) -> None:
    """A tail carrying only the panel: the page's body is the panel's, with the card."""
    assert fleet.put("/aircraft/HIGH/locations", json={"locations": ["panel"]}).status_code == 200
    body = fleet.get("/aircraft/HIGH/forecast").json()
    assert body["location"] == "panel"
    want, criterion = _by_hand(body["crack_as_of"]["p50"])
    page = fleet.get("/pages/aircraft/HIGH").text
    card = page[page.index('id="residual-strength"') :]
    card = card[: card.index("</div>")]
    value = re.search(r'data-value="([^"]+)"', card)
    assert value is not None and float(value.group(1)) == pytest.approx(want, rel=1e-9)
    margin = re.search(r'class="margin" data-value="([^"]+)">([^<]+)<', card)
    assert margin is not None
    assert float(margin.group(1)) == pytest.approx(want / 150.0 - 1, rel=1e-9)
    assert html.unescape(margin.group(2)) == fmt.signed_percent(want / 150.0 - 1)
    assert fmt.criterion_words(criterion) in card
    assert body["residual_strength"]["p50"]["residual_strength_mpa"] == pytest.approx(want)


def test_a_new_limit_stress_reaches_the_kept_answer(fleet: TestClient) -> None:
    """The aircraft's answer is kept under its rows' stamps; replacing the entry drops its rows,
    so the next answer's line reads the new limit stress."""
    before = fleet.get("/aircraft/HIGH/forecast").json()
    assert fleet.get("/aircraft/HIGH/forecast").json() == before  # kept
    assert (
        fleet.put("/locations/panel", json={**PANEL, "limit_stress_mpa": 120.0}).status_code == 200
    )
    after = fleet.get("/aircraft/HIGH/forecast").json()
    line = next(line for line in after["locations"] if line["location"] == "panel")
    strength = line["residual_strength"]
    want, _ = _by_hand(line["crack_as_of_m"])
    assert strength["limit_stress_mpa"] == 120.0
    assert strength["margin"] == pytest.approx(want / 120.0 - 1, rel=1e-9)


@contextmanager
def served_table_location(tmp_path: Path) -> Iterator[TestClient]:
    """A served fleet under FLEETPINN_MATERIAL 2024-T3 whose only location with a model is a
    table one (typed a_crit, no limit stress), "lug": tails LOW and HIGH, LOW inspected there
    once, retrained."""
    settings = settings_in(tmp_path).model_copy(update={"material": "2024-T3"})
    lug = {"geometry_table": {"crack_length_m": [0.001, 0.05], "factor": [1.1, 1.5]}}
    with serving(settings) as client:
        for tail, stress in (("LOW", 100.0), ("HIGH", 150.0)):
            add_tail(client, tail, 40, stress=stress)
        assert client.put("/locations/lug", json=lug).status_code == 201
        at_lug = {
            "inspection_id": "L1",
            "inspected_at": (START + timedelta(days=10)).isoformat(),
            "crack_length_m": 0.00501,  # a0 is 2024-T3's 5 mm
            "location": "lug",
        }
        assert client.post("/aircraft/LOW/inspections", json=at_lug).status_code == 201
        for name, job in client.post("/models/retrain").json()["jobs"].items():
            assert wait_for_job(client, job)["status"] == "succeeded", name
        yield client


def test_a_table_location_without_a_limit_stress_answers_as_before(tmp_path: Path) -> None:
    """Issue 41's goal for a table location of today's catalogue (typed a_crit, no limit
    stress): under FLEETPINN_MATERIAL its toughness is the material's, yet with no limit stress
    to hold it against its forecast and its line answer without `residual_strength`."""
    with served_table_location(tmp_path) as client:
        own = client.get("/aircraft/HIGH/locations/lug/forecast")
        assert own.status_code == 200, own.text
        assert set(own.json()) - OPTIONAL_BEFORE == KEYS_BEFORE
        aircraft = client.get("/aircraft/HIGH/forecast")
        lines = aircraft.json()["locations"]
        assert {line["location"]: set(line) for line in lines} == {"lug": LINE_KEYS_BEFORE}
        assert "residual_strength" not in aircraft.text
