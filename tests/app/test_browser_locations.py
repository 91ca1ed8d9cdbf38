"""A fleet whose aircraft carry only their own locations, in headless Chromium over a real
uvicorn: the tail page titles each chart with its location, names the governing one, keeps its
y axis within 1.5 a_crit, and Models & jobs shows the location of every version and job; the
catalogue page draws and says each crack case's limits."""

from __future__ import annotations

from datetime import timedelta
from pathlib import Path

import httpx
import pytest
from selenium.webdriver.common.by import By
from selenium.webdriver.remote.webdriver import WebDriver
from selenium.webdriver.remote.webelement import WebElement

from app import commands
from app.config import Settings
from app.local_server import wait_for_job
from app.web.charts import CLIP_FRACTION
from tests.app.conftest import SQLITE_ONLY_SERVER, START, flights
from tests.app.test_browser import _wait_for, browser, log_in  # noqa: F401

# server: the real uvicorn fixture (and the database it serves)
from tests.app.test_e2e import server, server_database, server_log  # noqa: F401

pytestmark = SQLITE_ONLY_SERVER

# the wing sees twice the recorded stress towards a small a_crit: its band passes it
WING = {"stress_factor": 2.0, "initial_crack_m": 0.002, "critical_crack_m": 0.012}
KEEL = {"stress_factor": 1.0, "initial_crack_m": 0.002, "critical_crack_m": 0.03}


@pytest.fixture(scope="module")
def fleet(server: httpx.Client) -> httpx.Client:  # noqa: F811
    """Two tails carrying wing and keel (not default), each inspected at both, retrained."""
    for name, entry in (("wing", WING), ("keel", KEEL)):
        assert server.put(f"/locations/{name}", json=entry).status_code == 201
    for tail, stress in (("L1", 150.0), ("L2", 250.0)):
        assert server.put(f"/aircraft/{tail}").status_code == 201
        assert server.put(f"/aircraft/{tail}/locations", json={"locations": ["wing", "keel"]})
        cycled = flights(60, stress=[stress, 1.4 * stress, 0.7 * stress])
        assert server.post(f"/aircraft/{tail}/flights", json=cycled).status_code == 201
        for name in ("wing", "keel"):
            body = {
                "inspection_id": f"{tail}-{name}",
                "inspected_at": (START + timedelta(days=5)).isoformat(),
                "crack_length_m": 0.0025,
                "location": name,
            }
            assert server.post(f"/aircraft/{tail}/inspections", json=body).status_code == 201
    accepted = server.post("/models/retrain").json()
    assert set(accepted["jobs"]) == {"wing", "keel"}
    for job_id in accepted["jobs"].values():
        assert wait_for_job(server, job_id)["status"] == "succeeded"
    return server


@pytest.fixture(scope="module")
def logged_in(
    browser: WebDriver,  # noqa: F811
    fleet: httpx.Client,
    server_database: Settings,  # noqa: F811
) -> WebDriver:
    key = commands.create_key("read", "browser", settings=server_database).key
    base = str(fleet.base_url).rstrip("/")
    log_in(browser, base, key)
    return browser


def _y_top_mm(driver: WebDriver, chart: str) -> float:
    """The chart's y axis top in mm, from the a_crit line's and the axes' drawn positions."""
    script = f"""
        const svg = document.querySelector('{chart} svg');
        const axes = svg.querySelector('#patch_2') || svg.querySelector('[id^=axes_] path');
        const line = svg.querySelector('#a-crit path');
        const a = axes.getBBox(), c = line.getBBox();
        return [a.y, a.y + a.height, c.y];
    """
    top, bottom, critical_y = driver.execute_script(script)
    return (bottom - top) / (bottom - critical_y)  # in units of a_crit


def test_a_multi_location_tail_page_in_chromium(
    logged_in: WebDriver, fleet: httpx.Client, tmp_path: Path
) -> None:
    driver = logged_in
    base = str(fleet.base_url).rstrip("/")
    aircraft = fleet.get("/aircraft/L2/forecast").json()
    governing = aircraft["governing_location"]
    driver.get(f"{base}/pages/aircraft/L2")
    _wait_for(driver, "#forecast-chart svg #band")
    assert driver.find_element(By.ID, "governing").text.startswith(
        f"Governing location: {governing}"
    )
    titles = driver.execute_script(
        "return [...document.querySelectorAll('figure.chart svg')].map(s => s.textContent)"
    )
    assert len(titles) == 2
    for name in ("wing", "keel"):
        assert sum(f"L2 at {name}: " in t for t in titles) == 1
    # the wing's band passes a_crit: its axis stops at 1.5 a_crit and says so
    wing = "#forecast-chart" if governing == "wing" else "#location-wing"
    assert driver.find_elements(By.CSS_SELECTOR, f"{wing} svg #clipped")
    assert _y_top_mm(driver, wing) <= CLIP_FRACTION + 1e-6
    driver.save_screenshot(str(tmp_path / "tail.png"))

    driver.get(f"{base}/pages/models")
    _wait_for(driver, "table#models")
    header = [th.text for th in driver.find_elements(By.CSS_SELECTOR, "table#models th")]
    assert header[1] == "Location"
    shown = {
        row.find_element(By.CSS_SELECTOR, "td.location").text
        for row in driver.find_elements(By.CSS_SELECTOR, "table#models tbody tr")
    }
    assert shown == {"wing", "keel"}
    active = driver.find_element(By.ID, "active-models").text
    for version in fleet.get("/models").json():
        assert f"{version['location']} v{version['version']}" in active
    jobs = {
        row.find_element(By.CSS_SELECTOR, "td.location").text
        for row in driver.find_elements(By.CSS_SELECTOR, "table#jobs tbody tr")
    }
    assert jobs == {"wing", "keel"}


# a surface crack whose Newman-Raju range (a/t = 0.8: 7.84 mm) ends before its section does at
# a = t (9.8 mm): its limit lies on both plots' crack axes, the panel's (105 mm) beyond both
STRINGER = {
    "crack_case": {"type": "surface_crack", "thickness_m": 0.0098, "width_m": 0.2,
                   "aspect_ratio": 0.8},
    "initial_crack_m": 0.001, "limit_stress_mpa": 120.0,
    "fracture_toughness_mpa_sqrt_m": 90.0, "yield_strength_mpa": 345.0,
}  # fmt: skip
PANEL = {
    "crack_case": {"type": "centre_crack", "width_m": 0.3, "method": "feddersen"},
    "initial_crack_m": 0.002,
    "limit_stress_mpa": 150.0,
    "fracture_toughness_mpa_sqrt_m": 80.0,
    "yield_strength_mpa": 345.0,
}


def _plots(driver: WebDriver, name: str) -> list[dict[str, object]]:
    """Each plot of a location's chart as drawn: its plot area's, legend's, validity line's and
    a_crit line's boxes on the screen (None where not drawn), and its legend's text."""
    script = """
        const box = el => el ? el.getBoundingClientRect().toJSON() : null;
        return [...document.querySelectorAll(arguments[0] + ' svg [id^=axes_]')]
            .filter(axes => axes.querySelector('[id^=plot-]'))
            .map(axes => ({
                plot: box(axes.querySelector('[id^=plot-]')),
                legend: box(axes.querySelector('[id^=legend-]')),
                legend_text: axes.querySelector('[id^=legend-]').textContent,
                validity: box(axes.querySelector('#validity-limit path')),
                beyond: !!axes.querySelector('#validity-beyond'),
                critical: box(axes.querySelector('#a-crit path')),
            }));
    """
    plots: list[dict[str, object]] = driver.execute_script(script, f"#location-{name}")
    return plots


def _said(element: WebElement, css: str) -> str:
    return element.find_element(By.CSS_SELECTOR, css).text.replace("\u00a0", " ")


def test_the_catalogue_page_in_chromium(
    logged_in: WebDriver, fleet: httpx.Client, tmp_path: Path
) -> None:
    """Reached from the navigation: a crack case's row names its a_crit and criterion, the
    dimension that ends a section, and the residual strength at a0 with what sets it (by hand:
    the panel's net section 345 (W - 2 a0) / W = 340 MPa); its charts draw beta(a) and the
    residual strength crossing the limit stress at a_crit, the case's validity limit on both
    plots where it lies on their crack axis (else said in the legend), each legend below its
    plot; no dimension or value splits over two lines."""
    stored = fleet.put("/locations/panel", json=PANEL)
    assert stored.status_code == 201, stored.text
    a_crit = stored.json()["critical_crack"]["crack_length_m"]
    assert fleet.put("/locations/stringer", json=STRINGER).status_code == 201
    driver = logged_in
    driver.get(str(fleet.base_url).rstrip("/") + "/pages/models")
    driver.find_element(By.LINK_TEXT, "Locations").click()
    _wait_for(driver, "#location-stringer svg #residual-strength")
    row = driver.find_element(By.ID, "row-panel")
    shown = row.find_element(By.CSS_SELECTOR, "td.a-crit span").get_attribute("data-value")
    assert float(shown or "nan") == pytest.approx(a_crit)
    assert "fracture" in row.find_element(By.CSS_SELECTOR, "td.reason").text
    net = 345.0 * (0.3 - 2 * 0.002) / 0.3
    assert _said(row, "td.strength .value") == f"{net:.0f} MPa at a0 = 2.00 mm"
    assert _said(row, "td.strength .governs") == "set by net-section yield at 345 MPa"
    assert _said(row, "td.strength .margin") == (
        f"margin +{(net / 150 - 1) * 100:.1f} % on the limit stress 150 MPa"
    )
    stringer = driver.find_element(By.ID, "row-stringer")
    assert "before the section ends at a = 9.80 mm; a = t: the crack reaches the back face" in (
        _said(stringer, "td.reason")
    )
    assert _said(stringer, "td.reason .warning").startswith(
        "a_crit lies beyond the validity limit a = 7.84 mm, a/t = 0.8 (Newman-Raju)"
    )
    # net-section yield sets the strength of the short cracks (shaded), fracture the longer
    for element in ("beta", "limit-stress", "a-crit", "net-section-yield"):
        assert driver.find_elements(By.CSS_SELECTOR, f"#location-panel svg #{element}"), element
    drawn = {name: _plots(driver, name) for name in ("panel", "stringer")}
    for name, plots in drawn.items():
        assert len(plots) == 2, name  # beta(a) and the residual strength
        for plot in plots:
            assert plot["legend"]["top"] >= plot["plot"]["bottom"], name  # type: ignore[index]
    for plot in drawn["stringer"]:
        line, area = plot["validity"], plot["plot"]
        assert line is not None and not plot["beyond"]
        assert area["left"] < line["left"] < plot["critical"]["left"]  # type: ignore[index]
        assert "validity limit 7.84 mm, a/t = 0.8 (Newman-Raju)" in plot["legend_text"]  # type: ignore[operator]
    for plot in drawn["panel"]:
        assert plot["validity"] is None and plot["beyond"]
        assert (
            "validity limit 105.00 mm, 2a/W = 0.7 (feddersen): beyond this axis"
            in (
                plot["legend_text"]  # type: ignore[operator]
            )
        )
    lines = driver.execute_script(
        "return [...document.querySelectorAll('#locations .dimension, #locations .value')]"
        ".map(e => [e.textContent, e.getClientRects().length])"
    )
    assert lines and all(count == 1 for _, count in lines), lines
    # wing and keel (constant F, typed a_crit) are listed without a chart
    listed = [r.get_attribute("id") for r in driver.find_elements(By.CSS_SELECTOR, "#locations tbody tr")]  # fmt: skip
    assert {"row-wing", "row-keel", "row-panel", "row-stringer"} <= set(listed)
    assert not driver.find_elements(By.ID, "location-wing")
    driver.save_screenshot(str(tmp_path / "locations.png"))
