"""The catalogue page (/pages/locations): each location's beta(a) chart, a_crit and its reason,
and the residual-strength curve, through the app in-process."""

from __future__ import annotations

import math
import re

import pytest
from fastapi.testclient import TestClient

from model.crack_cases.centre import CentreCrack
from model.crack_cases.residual_strength import Toughness, critical_crack

PANEL = {
    "description": "Fuselage skin panel",
    "crack_case": {"type": "centre_crack", "width_m": 0.3, "method": "feddersen"},
    "initial_crack_m": 0.002,
    "limit_stress_mpa": 150.0,
    "fracture_toughness_mpa_sqrt_m": 80.0,
    "yield_strength_mpa": 345.0,
}
SPLICE = {
    "geometry_table": {"crack_length_m": [0.002, 0.05], "factor": [1.12, 1.4]},
    "critical_crack_m": 0.04,
}


def _row(page: str, name: str) -> str:
    found = re.search(rf'<tr id="row-{name}">(.*?)</tr>', page, re.S)
    assert found, name
    return found.group(1)


def test_the_catalogue_page_shows_each_locations_beta_critical_crack_and_strength(
    client: TestClient,
) -> None:
    assert client.put("/locations/panel", json=PANEL).status_code == 201
    assert client.put("/locations/splice", json=SPLICE).status_code == 201
    answer = client.get("/pages/locations")
    assert answer.status_code == 200, answer.text
    page = answer.text
    assert 'href="/pages/locations" aria-current="page">Locations</a>' in page
    want = critical_crack(
        CentreCrack(0.3, "feddersen"), 150.0, Toughness(80.0, "given", 345.0), 0.002
    )
    panel = _row(page, "panel")
    shown = float(re.search(r'data-value="([0-9.e-]+)"', panel).group(1))  # type: ignore[union-attr]
    assert shown == want.crack_length_m
    assert f"{want.crack_length_m * 1000:.1f}" in panel  # in mm
    assert "computed at 150 MPa: fracture" in panel and "80 MPa√m (given), yield 345 MPa" in panel
    assert "centre_crack (width_m 0.3, method feddersen)" in panel
    # a typed a_crit says so; a table without a toughness draws beta alone
    splice = _row(page, "splice")
    assert "typed in the catalogue" in splice and "40.0" in splice and "table of 2 points" in splice
    default = _row(page, "default")
    assert "constant F = 1" in default and "the service&#39;s default" in default
    charts = dict(re.findall(r'<section id="location-([a-z]+)">(.*?)</section>', page, re.S))
    assert set(charts) == {"panel", "splice"}  # a constant factor has no curve to draw
    for element in ("beta", "residual-strength", "limit-stress", "a-crit"):
        assert f'id="{element}"' in charts["panel"], element
    assert 'id="beta"' in charts["splice"] and 'id="residual-strength"' not in charts["splice"]
    assert "panel: residual strength" in charts["panel"]
    # the strength the chart draws at a_crit is the limit stress, by hand (Feddersen's secant)
    a = want.crack_length_m
    assert 80.0 / math.sqrt(math.pi * a / math.cos(math.pi * a / 0.3)) == pytest.approx(150.0)


def test_the_fleet_pages_navigation_links_the_catalogue(client: TestClient) -> None:
    page = client.get("/pages/models").text
    assert '<a href="/pages/locations">Locations</a>' in page
