"""The catalogue page (/pages/locations): each location's beta(a) chart, a_crit and its reason,
and the residual-strength curve, through the app in-process."""

from __future__ import annotations

import math
import re

import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.services.records.locations import list_locations
from app.web.catalogue import catalogue_rows
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


def test_the_strength_chart_shades_where_net_section_yield_governs(
    client: TestClient, settings: Settings
) -> None:
    """The panel's curve kinks where net-section yield (345 (W - 2a) / W) gives way to fracture
    (Feddersen's secant at K = 80): the chart shades the cracks where yield sets it, the
    criterion at each point being the smaller strength's, by hand; a table with a material and
    no limit stress says so in its legend instead of a limit line."""
    assert client.put("/locations/panel", json=PANEL).status_code == 201
    lug = {"geometry_table": SPLICE["geometry_table"], "material": "2024-T3"}
    assert client.put("/locations/lug", json=lug).status_code == 201
    with client.app.state.session_factory() as session:  # type: ignore[attr-defined]
        rows = {r.name: r for r in catalogue_rows(list_locations(session), settings)}
    curves = rows["panel"].curves
    assert curves is not None and curves.strength_criterion is not None
    assert curves.strength_crack_m is not None
    for a, criterion in zip(curves.strength_crack_m, curves.strength_criterion, strict=True):
        by_fracture = 80.0 / math.sqrt(math.pi * a / math.cos(math.pi * a / 0.3))
        by_yield = 345.0 * (0.3 - 2 * a) / 0.3
        assert criterion == ("fracture" if by_fracture < by_yield else "net_section_yield")
    assert {"fracture", "net_section_yield"} == set(curves.strength_criterion)
    page = client.get("/pages/locations").text
    charts = dict(re.findall(r'<section id="location-([a-z]+)">(.*?)</section>', page, re.S))
    assert 'id="net-section-yield"' in charts["panel"]
    assert "net-section yield governs" in charts["panel"]
    # 2024-T3's K_IC alone, no yield strength: fracture throughout, nothing shaded
    assert (
        'id="residual-strength"' in charts["lug"] and 'id="net-section-yield"' not in charts["lug"]
    )
    assert "no limit stress given" in charts["lug"] and 'id="limit-stress"' not in charts["lug"]
    assert "no limit stress given" not in charts["panel"]
