"""The catalogue page (/pages/locations): each location's beta(a) chart, a_crit and its reason,
and the residual-strength curve, through the app in-process."""

from __future__ import annotations

import math
import re
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.services.records.locations import list_locations
from app.web.catalogue import catalogue_rows
from model.crack_cases.centre import CentreCrack
from model.crack_cases.residual_strength import Toughness, critical_crack

if TYPE_CHECKING:
    from matplotlib.axes import Axes

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


def _text(html: str) -> str:
    """The page's text as read (no-break spaces, which keep a number with its unit, as spaces;
    no space before a comma that follows a tag)."""
    return re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", html)).replace(" ,", ",")


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
    shown = re.search(r'data-value="([0-9.e-]+)"', _row(page, "panel")).group(1)  # type: ignore[union-attr]
    assert float(shown) == want.crack_length_m
    panel = _text(_row(page, "panel"))
    assert f"{want.crack_length_m * 1000:.2f}" in panel  # in mm
    assert "computed at the limit stress 150 MPa: fracture: K = beta S sqrt(pi a) reaches 80" in (
        panel
    )
    assert "toughness 80 MPa√m (fracture_toughness_mpa_sqrt_m), yield strength 345 MPa" in panel
    assert "centre_crack width 300.00, method feddersen" in panel  # mm in the header
    # a typed a_crit says so; a table without a toughness draws beta alone
    splice = _text(_row(page, "splice"))
    assert "typed in the catalogue" in splice and "40.00" in splice
    assert "table of 2 points a 2.00–50.00" in splice
    default = _text(_row(page, "default"))
    assert "constant F = 1" in default and "the service&#39;s default" in default
    header = re.search(r"<thead>(.*?)</thead>", page, re.S).group(1)  # type: ignore[union-attr]
    assert "Geometry and toughness (lengths in mm)" in header and "a_crit (mm)" in header
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


# a surface crack whose Newman-Raju range ends at a/t = 0.8 (7.84 mm) before its section does
STRINGER = {
    "crack_case": {
        "type": "surface_crack",
        "thickness_m": 0.0098,
        "width_m": 0.2,
        "aspect_ratio": 0.8,
    },
    "initial_crack_m": 0.001,
    "limit_stress_mpa": 120.0,
    "fracture_toughness_mpa_sqrt_m": 90.0,
    "yield_strength_mpa": 345.0,
}


def test_the_catalogue_says_every_crack_length_in_mm_and_the_validity_limit(
    client: TestClient,
) -> None:
    """The geometry's dimensions and the validity note in mm like a_crit beside them (no length
    in m on the page); a_crit past the case's validity limit is said in the row and the limit
    drawn on the chart, with beta held from there as the march reads it."""
    assert client.put("/locations/stringer", json=STRINGER).status_code == 201
    assert client.put("/locations/panel", json=PANEL).status_code == 201
    page = client.get("/pages/locations").text
    stringer = _text(_row(page, "stringer"))
    assert "surface_crack thickness 9.80, width 200.00, a/c 0.8" in stringer
    assert "9.80" in stringer  # a_crit: the section ends at a = t before either criterion
    assert "a_crit lies beyond the validity limit a = 7.84 mm, a/t = 0.8 (Newman-Raju)" in stringer
    tables = re.findall(r'<table class="listing" id="locations">.*?</table>', page, re.S)
    assert not re.search(r"\d m\b", _text(tables[0]))  # no length in m anywhere in the table
    charts = dict(re.findall(r'<section id="location-([a-z]+)">(.*?)</section>', page, re.S))
    assert 'id="validity-limit"' in charts["stringer"] and 'id="beta-held"' in charts["stringer"]
    assert "validity limit 7.84 mm, a/t = 0.8 (Newman-Raju)" in charts["stringer"]
    # the panel's a_crit (68.3 mm) lies well inside 2a/W = 0.7 (105 mm): no note, and the limit
    # lies beyond both plots' crack axes (to 85 mm), which say so
    assert "validity limit" not in _text(_row(page, "panel"))
    assert 'id="validity-limit"' not in charts["panel"]
    assert (
        _text(charts["panel"]).count(
            "validity limit 105.00 mm, 2a/W = 0.7 (feddersen): beyond this axis"
        )
        == 2
    )


def test_the_catalogue_names_what_ends_a_crack_and_what_sets_the_strength_at_a0(
    client: TestClient,
) -> None:
    """No "extent": a crack that reaches the end of its section names the dimension (a = t);
    the residual strength at a0 names its criterion and value, by hand: the panel's net section
    345 (W - 2 a0) / W = 340.4 MPa (fracture's 80 / (beta sqrt(pi a0)) is ~1000), the splice's
    fracture at 2024-T3's K_IC of 34 on its table's beta at the default a0 of 5 mm."""
    assert client.put("/locations/stringer", json=STRINGER).status_code == 201
    assert client.put("/locations/panel", json=PANEL).status_code == 201
    splice = {**SPLICE, "material": "2024-T3"}
    assert client.put("/locations/splice", json=splice).status_code == 201
    page = client.get("/pages/locations").text
    assert "extent" not in _text(page) and "end of its case" not in page
    stringer = _text(_row(page, "stringer"))
    assert "before the section ends at a = 9.80 mm; a = t: the crack reaches the back face" in (
        stringer
    )
    panel = _text(_row(page, "panel"))
    net = 345.0 * (0.3 - 2 * 0.002) / 0.3
    assert (
        f"{net:.0f} MPa at a0 = 2.00 mm set by net-section yield at 345 MPa margin "
        f"+{(net / 150 - 1) * 100:.1f} % on the limit stress 150 MPa"
    ) in panel
    beta = 1.12 + (1.4 - 1.12) * (0.005 - 0.002) / (0.05 - 0.002)
    by_fracture = 34.0 / (beta * math.sqrt(math.pi * 0.005))
    assert f"{by_fracture:.0f} MPa at a0 = 5.00 mm set by fracture at K_IC 34 MPa√m" in _text(
        _row(page, "splice")
    )


def test_the_location_charts_legends_lie_below_their_plots() -> None:
    """Each legend sits under its plot, outside the area its curves are drawn in, so it hides
    none of them (it once sat in the upper right, over a surface crack's flat strength curve)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from app.web.catalogue import Curves
    from app.web.location_charts import location_figure

    crack = tuple(0.001 * k for k in range(1, 11))
    curves = Curves(
        crack[:8],
        tuple(0.75 + 0.01 * k for k in range(8)),
        crack,
        tuple(345.0 - 3 * k for k in range(10)),
        120.0,
        0.0098,
        ("net_section_yield",) * 10,
        0.00784,
        "a/t = 0.8 (Newman-Raju)",
    )
    figure = location_figure("stringer", curves)
    FigureCanvasAgg(figure).draw()
    plots = [axes for axes in figure.axes if axes.get_legend() is not None]
    assert len(plots) == 2
    for axes in plots:
        legend = axes.get_legend()
        assert legend is not None
        assert legend.get_window_extent().y1 <= axes.get_window_extent().y0, axes.get_title()


def test_the_validity_limit_is_drawn_where_it_lies_on_each_plots_crack_axis() -> None:
    """beta(a) is drawn to a_crit (10 mm), the strength to 1.25 a_crit: a limit at 11.5 mm lies
    on the strength plot's crack axis alone, drawn there and said to lie beyond on beta's (its
    axis not stretched to reach it); a case without a limit on a says so."""
    from app.web.catalogue import Curves
    from app.web.location_charts import location_figure

    crack = tuple(0.001 * k for k in range(1, 11))
    strength_at = tuple(0.00125 * k for k in range(1, 11))
    curves = Curves(
        crack,
        tuple(1.0 + 0.01 * k for k in range(10)),
        strength_at,
        tuple(300.0 - 10 * k for k in range(10)),
        200.0,
        0.010,
        ("fracture",) * 10,
        0.0115,
        "a/W = 0.8 (tada)",
    )
    beta, strength = location_figure("strip", curves).axes

    def legend(axes: Axes) -> list[str]:
        drawn = axes.get_legend()
        assert drawn is not None, axes.get_title()
        return [text.get_text() for text in drawn.get_texts()]

    said = "validity limit 11.50 mm, a/W = 0.8 (tada)"
    assert [line.get_gid() for line in beta.get_lines()].count("validity-limit") == 0
    assert beta.get_xlim()[1] < 11.5
    assert f"{said}: beyond this axis" in legend(beta)
    drawn = [line for line in strength.get_lines() if line.get_gid() == "validity-limit"]
    assert len(drawn) == 1 and np.asarray(drawn[0].get_xdata(), float).tolist() == [11.5, 11.5]
    assert said in legend(strength)
    unbounded = location_figure("plate", replace(curves, validity_limit_m=None, validity_reason="an infinite plate (Bowie)"))  # fmt: skip
    for axes in unbounded.axes:
        assert "no validity limit on a: an infinite plate (Bowie)" in legend(axes)
