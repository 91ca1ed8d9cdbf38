"""The pages in a real browser: headless Chromium (Debian's chromium and chromium-driver, put in
place by `make browser`) drives a real uvicorn process serving a small seeded fleet.

Chromium resolves no host but 127.0.0.1 here, so a page that needed the internet (a CDN) would
fail to render.  Screenshots land in the test's tmp directory.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from datetime import timedelta
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import quote

import httpx
import pandas as pd
import pytest
from selenium import webdriver
from selenium.common.exceptions import StaleElementReferenceException
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys
from selenium.webdriver.remote.webdriver import WebDriver
from selenium.webdriver.support import expected_conditions as ec
from selenium.webdriver.support.ui import Select, WebDriverWait

from app import commands
from app.config import Settings
from app.local_server import wait_for_job
from app.web import format as fmt
from tests.app.conftest import SQLITE_ONLY_SERVER, START, flights

# server: the real uvicorn fixture (and the database it serves)
from tests.app.test_e2e import server, server_database, server_log  # noqa: F401

pytestmark = SQLITE_ONLY_SERVER

CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--window-size=1280,1000",
    # No name resolves but the test server's: any CDN request fails.
    "--host-resolver-rules=MAP * ~NOTFOUND , EXCLUDE 127.0.0.1",
)
STRESS = {"B1": 90.0, "B2": 120.0, "B3": 160.0, "B4": 220.0, "B5": 300.0}


@pytest.fixture(scope="module")
def browser(tmp_path_factory: pytest.TempPathFactory) -> Iterator[WebDriver]:
    if not (CHROMIUM.exists() and CHROMEDRIVER.exists()):
        pytest.skip(
            "Chromium is not installed (/usr/bin/chromium, /usr/bin/chromedriver): `make browser` "
            "installs Debian's chromium and chromium-driver, which needs root and apt access"
        )
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={tmp_path_factory.mktemp('chromium-profile')}")
    driver = webdriver.Chrome(options=options, service=Service(executable_path=str(CHROMEDRIVER)))
    driver.set_page_load_timeout(60)
    try:
        yield driver
    finally:
        driver.quit()


@pytest.fixture(scope="module")
def fleet(server: httpx.Client) -> httpx.Client:  # noqa: F811
    """Five tails, inspections of each kind, a trained model.  Each tail cycles three stress
    ranges over four flights a day, so its days differ and resampling them gives a band."""
    rows = [
        {"tail": t, **f}
        for t, s in STRESS.items()
        for f in flights(60, stress=[s, 1.4 * s, 0.7 * s])
    ]
    csv = pd.DataFrame(rows).to_csv(index=False)
    files = {"file": ("fleet.csv", csv, "text/csv")}
    assert server.post("/flights/upload", files=files).status_code == 201
    at = (START + timedelta(days=5)).isoformat()
    inspections = {
        "B1": {"inspection_id": "I1", "inspected_at": at, "crack_length_m": 0.00501},
        "B2": {
            "inspection_id": "I1",
            "inspected_at": at,
            "detected": False,
            "detection_threshold_m": 0.002,
        },
        "B4": {
            "inspection_id": "I1",
            "inspected_at": at,
            "crack_length_m": 0.0052,
            "repaired": True,
            "crack_after_repair_m": 0.004,
        },
    }
    for tail, body in inspections.items():
        assert server.post(f"/aircraft/{tail}/inspections", json=body).status_code == 201
    job = wait_for_job(server, server.post("/models/retrain").json()["job_id"])
    assert job["status"] == "succeeded", job
    return server


@pytest.fixture(scope="module")
def logged_in(
    browser: WebDriver,
    fleet: httpx.Client,
    server_database: Settings,  # noqa: F811
) -> WebDriver:
    """The browser logged in with a read key: the fleet page sends it to the login form first,
    and back to the fleet page after."""
    key = commands.create_key("read", "browser", settings=server_database).key
    base = str(fleet.base_url).rstrip("/")
    browser.get(f"{base}/")
    _wait_for(browser, "form#login input#key")
    assert browser.current_url == f"{base}/pages/login?next=/"
    browser.find_element(By.ID, "key").send_keys(key)
    browser.find_element(By.CSS_SELECTOR, "form#login button").click()
    _wait_for(browser, "table#ranking")
    return browser


def log_in(driver: WebDriver, base: str, key: str) -> None:
    """Log in at base's login form with `key`; returns on the fleet page it leads to."""
    driver.get(f"{base}/pages/login")
    _wait_for(driver, "form#login input#key")
    driver.find_element(By.ID, "key").send_keys(key)
    driver.find_element(By.CSS_SELECTOR, "form#login button").click()
    _wait_for(driver, "table#ranking")


def _wait_for(driver: WebDriver, css: str) -> None:
    WebDriverWait(driver, 30).until(ec.presence_of_element_located((By.CSS_SELECTOR, css)))


def _only_local_requests(driver: WebDriver, base: str) -> None:
    """Every resource the page asked for came from the server."""
    loaded = driver.execute_script(
        "return performance.getEntriesByType('resource').map(e => e.name)"
    )
    assert loaded, "the page loaded no resource"
    assert [url for url in loaded if not url.startswith(base)] == []


def test_fleet_page_and_tail_page_in_chromium(
    logged_in: WebDriver, fleet: httpx.Client, tmp_path: Path
) -> None:
    browser = logged_in
    base = str(fleet.base_url).rstrip("/")
    browser.get(f"{base}/")
    _wait_for(browser, "table#ranking tbody tr")
    table = browser.find_element(By.CSS_SELECTOR, "table#ranking")
    horizon = table.get_attribute("data-horizon-days")
    ranking = fleet.get("/fleet/ranking", params={"limit": 100, "horizon_days": horizon}).json()
    rows = table.find_elements(By.CSS_SELECTOR, "tbody tr")
    assert [r.get_attribute("data-tail") for r in rows] == [i["tail"] for i in ranking["items"]]
    for row, item in zip(rows, ranking["items"], strict=True):
        crack = row.find_element(By.CSS_SELECTOR, "td.col-crack .main").text
        band = row.find_element(By.CSS_SELECTOR, "td.col-crack .band").text
        prob = row.find_element(By.CSS_SELECTOR, "td.col-prob").text
        expected_band = item["crack_as_of_band"]
        critical = ranking["critical_crack_m"]
        assert crack == fmt.crack_mm(expected_band["p50"], critical)
        assert band == fmt.crack_band(expected_band["p05"], expected_band["p95"], critical)
        assert prob == fmt.percent(item["prob_critical"])
    _only_local_requests(browser, base)
    browser.save_screenshot(str(tmp_path / "fleet.png"))

    top = ranking["items"][0]["tail"]
    rows[0].find_element(By.CSS_SELECTOR, "td.col-tail a").click()
    _wait_for(browser, "#forecast-chart svg #band")
    assert browser.current_url == f"{base}/pages/aircraft/{top}"
    assert browser.find_element(By.CSS_SELECTOR, "#forecast-chart svg #a-crit")
    # the estimated crack over the recorded flights runs into the projection
    assert browser.find_element(By.CSS_SELECTOR, "#forecast-chart svg #history")
    box = browser.execute_script(
        "const b = document.querySelector('#forecast-chart svg #band').getBBox();"
        "return [b.width, b.height];"
    )
    assert box[0] > 100 and box[1] > 10  # the band spans the chart and has a width
    assert browser.find_element(By.TAG_NAME, "h1").text == top
    browser.save_screenshot(str(tmp_path / "tail.png"))
    assert (tmp_path / "fleet.png").stat().st_size > 10_000
    assert (tmp_path / "tail.png").stat().st_size > 10_000


def _shown_tails(driver: WebDriver) -> list[str | None]:
    rows = driver.find_elements(By.CSS_SELECTOR, "table#ranking tbody tr")
    return [r.get_attribute("data-tail") for r in rows]


def test_stale_banner_past_critical_and_search_in_chromium(
    logged_in: WebDriver, fleet: httpx.Client
) -> None:
    """A new user sees how many tails are stale, which are past critical (a flag and a date,
    never a length), and finds a tail by typing its name."""
    browser = logged_in
    base = str(fleet.base_url).rstrip("/")
    late = (START + timedelta(days=3 * 365)).date().isoformat()
    browser.get(f"{base}/?as_of={late}")
    _wait_for(browser, "#stale-banner")
    banner = browser.find_element(By.ID, "stale-banner").text
    assert banner.startswith(f"{len(STRESS)} of {len(STRESS)} tails have stale data"), banner
    ranking = fleet.get("/fleet/ranking", params={"as_of": late, "limit": 100}).json()
    past = [i for i in ranking["items"] if i["past_critical"]]
    assert past, "no tail past critical"
    for item in past:
        cell = browser.find_element(By.CSS_SELECTOR, f'tr[data-tail="{item["tail"]}"] td.col-crack')
        shown = " ".join(cell.text.split()).lower()  # the tag is set in capitals
        assert shown == f"past critical since {item['past_critical_since'][:10]}", shown
    # a p50 at a_crit is a flag and a date, never a length (a band's p95 may read "beyond
    # critical (> a_crit mm)")
    medians = browser.find_elements(By.CSS_SELECTOR, "#ranking td.col-crack .main")
    assert medians and not any(cell.text.startswith("beyond critical") for cell in medians)

    box = browser.find_element(By.ID, "q")
    box.clear()
    box.send_keys("b3", Keys.ENTER)
    # the rows of the page before the search go stale while the next one loads
    WebDriverWait(browser, 30, ignored_exceptions=[StaleElementReferenceException]).until(
        lambda d: _shown_tails(d) == ["B3"]
    )
    assert browser.find_element(By.ID, "shown-count").text == "1"
    assert browser.find_element(By.ID, "as-of").text == late  # the search kept the as-of date

    # filter to overdue: the rows shown are the overdue ones, as many as the card counts
    box = browser.find_element(By.ID, "q")
    box.clear()
    Select(browser.find_element(By.ID, "show")).select_by_value("overdue")
    browser.find_element(By.CSS_SELECTOR, "form#fleet-filter button").click()
    WebDriverWait(browser, 30).until(ec.url_contains("show=overdue"))
    overdue = [i["tail"] for i in ranking["items"] if i["overdue"]]
    assert overdue, "no tail overdue"
    assert sorted(_shown_tails(browser)) == sorted(overdue)
    card = browser.find_element(By.CSS_SELECTOR, "#count-overdue dd").text
    assert card == browser.find_element(By.ID, "shown-count").text == str(len(overdue))


def test_tail_page_shows_inspections_in_chromium(logged_in: WebDriver, fleet: httpx.Client) -> None:
    browser = logged_in
    base = str(fleet.base_url).rstrip("/")
    browser.get(f"{base}/pages/aircraft/B4")
    _wait_for(browser, "#forecast-chart svg #inspections-repair")
    findings = browser.find_element(By.CSS_SELECTOR, "#inspections").text
    assert "5.20 mm; repaired to 4.00 mm" in findings


def test_api_docs_render_offline_in_chromium(
    browser: WebDriver, fleet: httpx.Client, tmp_path: Path
) -> None:
    base = str(fleet.base_url).rstrip("/")
    browser.get(f"{base}/docs")
    _wait_for(browser, ".swagger-ui .opblock")
    operations = browser.find_elements(By.CSS_SELECTOR, ".swagger-ui .opblock-summary-path")
    assert "/fleet/ranking" in {o.get_attribute("data-path") for o in operations}
    _only_local_requests(browser, base)
    browser.save_screenshot(str(tmp_path / "docs.png"))
    # "Try it out" starts from the schema's example body
    operation = "operations-inspections-post_inspections_aircraft__tail__inspections_post"
    browser.find_element(By.CSS_SELECTOR, f"#{operation} .opblock-summary").click()
    WebDriverWait(browser, 30).until(
        ec.text_to_be_present_in_element((By.ID, operation), '"inspection_id": "I-2025-01"')
    )
    browser.get(f"{base}/redoc")
    _wait_for(browser, ".redoc-wrap .api-content")
    # ReDoc's "API docs by Redocly" footer logo comes from the package too (app.routes.docs).
    _wait_for(browser, "img[alt='redocly logo']")
    _only_local_requests(browser, base)


def _attacker_page(action: str, key: str) -> str:
    """Another site's page whose form logs the visitor in with the attacker's key at once."""
    return (
        f'<html><body><form id="csrf" method="post" action="{action}">'
        f'<input name="key" value="{key}"><input name="next" value="/"></form>'
        "<script>document.getElementById('csrf').submit()</script></body></html>"
    )


@pytest.fixture
def attacker_site(fleet: httpx.Client, server_database: Settings) -> Iterator[str]:  # noqa: F811
    """A page on another origin (another port) holding a login-CSRF form with a valid key."""
    key = commands.create_key("read", "attacker", settings=server_database).key
    page = _attacker_page(f"{str(fleet.base_url).rstrip('/')}/pages/login", key).encode()

    class Page(BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            self.send_response(200)
            self.send_header("content-type", "text/html")
            self.send_header("content-length", str(len(page)))
            self.end_headers()
            self.wfile.write(page)

        def log_message(self, *args: object) -> None:
            pass

    site = ThreadingHTTPServer(("127.0.0.1", 0), Page)
    thread = threading.Thread(target=site.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{site.server_address[1]}/"
    finally:
        site.shutdown()
        site.server_close()


def test_a_cross_site_form_cannot_log_in_in_chromium(
    browser: WebDriver,
    fleet: httpx.Client,
    attacker_site: str,
    server_database: Settings,  # noqa: F811
) -> None:
    base = str(fleet.base_url).rstrip("/")
    browser.get(f"{base}/pages/login")
    browser.delete_all_cookies()
    key = commands.create_key("read", "attacker-data", settings=server_database).key
    data_page = "data:text/html," + quote(_attacker_page(f"{base}/pages/login", key))
    # another origin (another port), and an opaque one (a data: page: Origin null)
    for page in (attacker_site, data_page):
        browser.get(page)
        _wait_for(browser, "#login-error")
        assert "sent from another site" in browser.find_element(By.ID, "login-error").text
        assert browser.get_cookies() == []
        browser.get(f"{base}/")
        _wait_for(browser, "form#login input#key")
        assert browser.current_url == f"{base}/pages/login?next=/"
    # the login form of the site itself still logs in
    browser.find_element(By.ID, "key").send_keys(key)
    browser.find_element(By.CSS_SELECTOR, "form#login button").click()
    _wait_for(browser, "table#ranking")
    assert [c["name"] for c in browser.get_cookies()] != []
