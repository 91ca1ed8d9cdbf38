"""The residual strength where a user reads a tail, over a real uvicorn: the tail's page in
headless Chromium and `fleetpinn client forecast` show it (p50, the criterion, the margin on
the limit stress) for a location with a limit stress, and nothing for one without."""

from __future__ import annotations

import math
from datetime import timedelta

import httpx
import pytest
from selenium.webdriver.common.by import By
from selenium.webdriver.remote.webdriver import WebDriver

from app import commands
from app.cli import main
from app.config import Settings
from app.local_server import wait_for_job
from app.web import format as fmt
from tests.app.conftest import SQLITE_ONLY_SERVER, START, flights
from tests.app.test_browser import _wait_for, browser, log_in  # noqa: F401

# server: the real uvicorn fixture (and the database it serves)
from tests.app.test_e2e import server, server_database, server_log  # noqa: F401
from tests.app.test_location_crack_cases import PANEL

pytestmark = SQLITE_ONLY_SERVER


@pytest.fixture(scope="module")
def fleet(server: httpx.Client) -> httpx.Client:  # noqa: F811
    """BOTH carries the default location (constant F) and the panel (a centre crack with a
    limit stress), ONLY the panel alone; each inspected at what it carries, retrained."""
    assert server.put("/locations/panel", json=PANEL).status_code == 201
    for tail, stress in (("BOTH", 100.0), ("ONLY", 150.0)):
        assert server.put(f"/aircraft/{tail}").status_code == 201
        assert server.post(f"/aircraft/{tail}/flights", json=flights(40, stress=stress))
    assert server.put("/aircraft/ONLY/locations", json={"locations": ["panel"]}).status_code == 200
    for tail, location, crack in (("BOTH", None, 0.00501), ("BOTH", "panel", 0.00201)):
        body = {
            "inspection_id": f"{tail}-{location}",
            "inspected_at": (START + timedelta(days=5)).isoformat(),
            "crack_length_m": crack,
            **({"location": location} if location else {}),
        }
        assert server.post(f"/aircraft/{tail}/inspections", json=body).status_code == 201
    for name, job in server.post("/models/retrain").json()["jobs"].items():
        assert wait_for_job(server, job)["status"] == "succeeded", name
    return server


def _by_hand(crack_m: float) -> float:
    """The panel's residual strength: Feddersen's secant at K = 80, net section 345 (W - 2a)/W."""
    by_fracture = 80.0 / math.sqrt(math.pi * crack_m / math.cos(math.pi * crack_m / 0.3))
    return min(by_fracture, 345.0 * (0.3 - 2 * crack_m) / 0.3)


def test_the_tail_pages_in_chromium(
    browser: WebDriver,  # noqa: F811
    fleet: httpx.Client,
    server_database: Settings,  # noqa: F811
) -> None:
    key = commands.create_key("read", "browser", settings=server_database).key
    base = str(fleet.base_url).rstrip("/")
    log_in(browser, base, key)
    # ONLY's body is the panel's: the card, at its p50 crack now
    only = fleet.get("/aircraft/ONLY/forecast").json()
    want = _by_hand(only["crack_as_of"]["p50"])
    browser.get(f"{base}/pages/aircraft/ONLY")
    _wait_for(browser, "#residual-strength")
    card = browser.find_element(By.ID, "residual-strength")
    value = card.find_element(By.CSS_SELECTOR, "[data-value]")
    assert float(value.get_attribute("data-value") or "nan") == pytest.approx(want, rel=1e-9)
    assert value.text == fmt.number(want, 0)
    assert fmt.signed_percent(want / 150.0 - 1) in card.text
    assert "on the limit 150 MPa" in card.text
    # BOTH's body is the default location's (no limit stress): no card; the panel's line has it
    line = next(
        line for line in fleet.get("/aircraft/BOTH/forecast").json()["locations"]
        if line["location"] == "panel"
    )  # fmt: skip
    browser.get(f"{base}/pages/aircraft/BOTH")
    _wait_for(browser, "#location-panel")
    assert browser.find_elements(By.ID, "residual-strength") == []
    shown = browser.find_element(By.CSS_SELECTOR, "#location-panel .residual-strength")
    assert shown.text == fmt.strength_words(**line["residual_strength"])
    assert float(shown.get_attribute("data-margin") or "nan") == pytest.approx(
        line["residual_strength"]["margin"], rel=1e-12
    )


def test_the_fleet_page_in_chromium_sorts_by_the_margin(
    browser: WebDriver,  # noqa: F811
    fleet: httpx.Client,
    server_database: Settings,  # noqa: F811
) -> None:
    """The fleet page's Strength margin column, sorted: the panel's rows by margin, smallest
    first, each the ranking's own; the default location's rows last with a dash."""
    key = commands.create_key("read", "browser-fleet", settings=server_database).key
    base = str(fleet.base_url).rstrip("/")
    log_in(browser, base, key)
    items = fleet.get("/fleet/ranking").json()["items"]
    margins = sorted(
        (i["residual_strength"]["margin"], i["tail"]) for i in items if "residual_strength" in i
    )
    browser.get(f"{base}/?sort=margin")
    _wait_for(browser, "table#ranking th.col-margin")
    cells = browser.find_elements(By.CSS_SELECTOR, "table#ranking tbody td.col-margin")
    values = [cell.get_attribute("data-value") for cell in cells]
    assert [float(v or "nan") for v in values[: len(margins)]] == [m for m, _ in margins]
    assert values[len(margins) :] == [None] * (len(items) - len(margins))
    assert [c.text for c in cells[len(margins) :]] == ["—"] * (len(items) - len(margins))
    assert fmt.signed_percent(margins[0][0]) in cells[0].text


def test_the_client_forecast_shows_it(
    fleet: httpx.Client, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("FLEETPINN_API_KEY", fleet.headers["authorization"].removeprefix("Bearer "))
    url = str(fleet.base_url).rstrip("/")
    only = fleet.get("/aircraft/ONLY/forecast").json()
    strength = only["residual_strength"]
    assert main(["client", "--url", url, "forecast", "ONLY"]) == 0
    table = capsys.readouterr().out
    row = next(line for line in table.splitlines() if "residual strength today (p50)" in line)
    p50 = strength["p50"]
    words = fmt.strength_words(p50["residual_strength_mpa"], p50["criterion"], p50["margin"], 150.0)
    assert words in row
    assert p50["residual_strength_mpa"] == pytest.approx(_by_hand(only["crack_as_of"]["p50"]))
    # BOTH: its body (the default location) shows none; the panel's line shows its own
    both = fleet.get("/aircraft/BOTH/forecast").json()
    panel = next(line for line in both["locations"] if line["location"] == "panel")
    assert main(["client", "--url", url, "forecast", "BOTH"]) == 0
    table = capsys.readouterr().out
    assert "residual strength today" not in table
    lines = [line for line in table.splitlines() if "location panel" in line]
    assert len(lines) == 1
    assert fmt.strength_words(**panel["residual_strength"]) in lines[0]
    default = next(line for line in table.splitlines() if "location default" in line)
    assert "residual strength" not in default


def test_the_client_ranking_shows_it(
    fleet: httpx.Client, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`fleetpinn client ranking`: a column after P(critical) with the residual strength and
    margin of each panel row (a dash on the default location's), and four CSV columns."""
    monkeypatch.setenv("FLEETPINN_API_KEY", fleet.headers["authorization"].removeprefix("Bearer "))
    url = str(fleet.base_url).rstrip("/")
    items = fleet.get("/fleet/ranking").json()["items"]
    assert main(["client", "--url", url, "ranking"]) == 0
    table = capsys.readouterr().out
    head = table[: table.index("┡")]
    assert "residual strength" in head and "margin" in head
    rows = [  # the table's rows (the title names the locations' models too)
        line
        for line in table.splitlines()
        if line.startswith("│") and (" panel " in line or " default " in line)
    ]
    assert len(rows) == len(items) == 3
    for item, row in zip(items, rows, strict=True):
        assert item["tail"] in row and item["location"] in row
        strength = item.get("residual_strength")
        if strength is None:
            assert item["location"] == "default" and "MPa" not in row
        else:
            assert fmt.strength_margin(strength["residual_strength_mpa"], strength["margin"]) in row
    assert main(["client", "--url", url, "ranking", "--csv"]) == 0
    lines = capsys.readouterr().out.splitlines()
    header = lines[0].split(",")
    at = header.index("prob_critical") + 1
    assert header[at : at + 4] == [
        "residual_strength_mpa", "residual_strength_criterion", "residual_strength_margin",
        "limit_stress_mpa",
    ]  # fmt: skip
    for item, line in zip(items, lines[1:], strict=True):
        cells = line.split(",")[at : at + 4]
        strength = item.get("residual_strength")
        if strength is None:
            assert cells == ["", "", "", ""]
        else:
            assert float(cells[0]) == strength["residual_strength_mpa"]
            assert cells[1] == strength["criterion"]
            assert float(cells[2]) == strength["margin"]
            assert float(cells[3]) == 150.0
