"""A tail's chart image and page: a flagged inspection drawn against what it was compared with
(the estimate after the last recorded flight before it) and said so, and a flights axis for
tests that live in cycles (`axis=flights`; another value is a 422 naming `axis`)."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from tests.app.conftest import START, add_tail, inspect, retrained, serving, settings_in


@pytest.fixture(scope="module")
def flagged(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """T1: 40 flights (10 days), a reading at day 5, retrained; then a 30 mm reading on day 8,
    far from the estimate after its last flight before it: flagged."""
    settings = settings_in(Path(tmp_path_factory.mktemp("axis")))
    with serving(settings) as client:
        add_tail(client, "T1", 40, stress=150.0)
        inspect(client, "T1", START + timedelta(days=5), 0.00502)
        retrained(client)
        inspect(client, "T1", START + timedelta(days=8, hours=1), 0.03)
        (found,) = [i for i in client.get("/aircraft/T1/inspections").json() if i["flagged"]]
        assert found["forecast_crack_m"] < 0.01
        yield client


def test_the_image_draws_a_flagged_finding_against_its_estimate(flagged: TestClient) -> None:
    found = next(i for i in flagged.get("/aircraft/T1/inspections").json() if i["flagged"])
    svg = flagged.get("/aircraft/T1/forecast.svg").text
    assert 'id="flagged-compared"' in svg and 'id="flagged-link"' in svg
    estimate = f"{found['forecast_crack_m'] * 1000:.2f} mm"
    # flights 4 a day from START: the last before day 8 01:00 flew on day 8 (its first)
    assert f"vs {estimate} (2024-01-09)" in svg
    assert "flagged: the estimate it was compared with" in svg


def test_the_flights_axis_on_the_image_and_the_page(flagged: TestClient) -> None:
    svg = flagged.get("/aircraft/T1/forecast.svg", params={"axis": "flights"}).text
    assert "flights flown" in svg and "2024-01-0" not in svg.split("flagged z=")[0][-2000:]
    assert flagged.get("/aircraft/T1/forecast.svg").text.count("flights flown") == 0
    page = flagged.get("/pages/aircraft/T1", params={"axis": "flights"})
    assert page.status_code == 200 and "flights flown" in page.text
    assert 'id="axis-date"' in page.text and 'id="axis-flights"' not in page.text
    assert "against the estimate of" in page.text and "(not today's projection)" in page.text
    refused = flagged.get("/aircraft/T1/forecast.png", params={"axis": "cycles"})
    assert refused.status_code == 422 and refused.json()["detail"][0]["loc"] == ["query", "axis"]
