"""A fleet whose aircraft carry only their own locations, in headless Chromium over a real
uvicorn: the tail page titles each chart with its location, names the governing one, keeps its
y axis within 1.5 a_crit, and Models & jobs shows the location of every version and job."""

from __future__ import annotations

from datetime import timedelta
from pathlib import Path

import httpx
import pytest
from selenium.webdriver.common.by import By
from selenium.webdriver.remote.webdriver import WebDriver

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


def test_the_catalogue_page_in_chromium(
    logged_in: WebDriver, fleet: httpx.Client, tmp_path: Path
) -> None:
    """Reached from the navigation: a crack case's row names its a_crit and criterion, and its
    chart draws beta(a) and the residual strength crossing the limit stress at a_crit."""
    panel = {
        "crack_case": {"type": "centre_crack", "width_m": 0.3, "method": "feddersen"},
        "initial_crack_m": 0.002,
        "limit_stress_mpa": 150.0,
        "fracture_toughness_mpa_sqrt_m": 80.0,
        "yield_strength_mpa": 345.0,
    }
    stored = fleet.put("/locations/panel", json=panel)
    assert stored.status_code == 201, stored.text
    a_crit = stored.json()["critical_crack"]["crack_length_m"]
    driver = logged_in
    driver.get(str(fleet.base_url).rstrip("/") + "/pages/models")
    driver.find_element(By.LINK_TEXT, "Locations").click()
    _wait_for(driver, "#location-panel svg #residual-strength")
    row = driver.find_element(By.ID, "row-panel")
    shown = row.find_element(By.CSS_SELECTOR, "td.a-crit span").get_attribute("data-value")
    assert float(shown or "nan") == pytest.approx(a_crit)
    assert "fracture" in row.find_element(By.CSS_SELECTOR, "td.reason").text
    # net-section yield sets the strength of the short cracks (shaded), fracture the longer
    for element in ("beta", "limit-stress", "a-crit", "net-section-yield"):
        assert driver.find_elements(By.CSS_SELECTOR, f"#location-panel svg #{element}"), element
    # wing and keel (constant F, typed a_crit) are listed without a chart
    listed = [r.get_attribute("id") for r in driver.find_elements(By.CSS_SELECTOR, "#locations tbody tr")]  # fmt: skip
    assert {"row-wing", "row-keel", "row-panel"} <= set(listed)
    assert not driver.find_elements(By.ID, "location-wing")
    driver.save_screenshot(str(tmp_path / "locations.png"))
