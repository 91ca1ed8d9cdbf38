"""HTML pages, chart images and the offline API docs, through the app in-process."""

from __future__ import annotations

import re
from datetime import timedelta
from html.parser import HTMLParser

import pytest
from fastapi.testclient import TestClient

from app.local_server import wait_for_job
from app.web import format as fmt
from tests.app.conftest import START, add_tail, inspect
from tests.app.snapshots import copied_for_each_test, served_settings


def _store_fleet(client: TestClient) -> None:
    """Three tails at constant stress (HIGH grows fastest), inspections of every kind, a model."""
    for tail, stress in (("LOW", 100.0), ("MID", 150.0), ("HIGH", 300.0)):
        add_tail(client, tail, 40, stress=stress)
    inspect(client, "LOW", START + timedelta(days=2), 0.00501)
    not_found = {
        "inspection_id": "NF1",
        "inspected_at": (START + timedelta(days=3)).isoformat(),
        "detected": False,
        "detection_threshold_m": 0.002,
    }
    repair = {
        "inspection_id": "R1",
        "inspected_at": (START + timedelta(days=4)).isoformat(),
        "crack_length_m": 0.0051,
        "repaired": True,
        "crack_after_repair_m": 0.004,
    }
    for body in (not_found, repair):
        assert client.post("/aircraft/MID/inspections", json=body).status_code == 201
    assert client.put("/aircraft/EMPTY").status_code == 201
    job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
    assert job["status"] == "succeeded", job["error"]


stored_database, fleet = copied_for_each_test("fleet", _store_fleet)


class _Table(HTMLParser):
    """Rows of the ranking table: {tail: {column class: (text, attributes)}}."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[dict[str, tuple[str, dict[str, str | None]]]] = []
        self.cell: str | None = None
        self.attrs: dict[str, str | None] = {}
        self.text: list[str] = []
        self.in_body = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        values = dict(attrs)
        if tag == "tbody":
            self.in_body = True
        elif tag == "tr" and self.in_body:
            self.rows.append({})
        elif tag == "td" and self.in_body:
            self.cell = next(c for c in (values.get("class") or "").split() if c.startswith("col-"))
            self.attrs, self.text = values, []

    def handle_endtag(self, tag: str) -> None:
        if tag == "td" and self.cell is not None:
            self.rows[-1][self.cell] = (" ".join("".join(self.text).split()), self.attrs)
            self.cell = None
        elif tag == "tbody":
            self.in_body = False

    def handle_data(self, data: str) -> None:
        if self.cell is not None:
            self.text.append(data)


def _table(html: str) -> list[dict[str, tuple[str, dict[str, str | None]]]]:
    parser = _Table()
    parser.feed(html)
    return parser.rows


def test_fleet_page_shows_the_json_ranking(fleet: TestClient) -> None:
    page = fleet.get("/")
    assert page.status_code == 200
    assert page.headers["content-type"].startswith("text/html")
    ranking = fleet.get("/fleet/ranking", params={"limit": 100}).json()
    rows = _table(page.text)
    assert [r["col-tail"][0] for r in rows] == [i["tail"] for i in ranking["items"]]
    for row, item in zip(rows, ranking["items"], strict=True):
        band = item["crack_as_of_band"]
        crack_text, crack_attrs = row["col-crack"]
        assert crack_attrs["data-value"] == repr(band["p50"])
        critical = ranking["critical_crack_m"]
        shown = [
            fmt.crack_mm(band["p50"], critical),
            fmt.crack_band(band["p05"], band["p95"], critical),
        ]
        assert crack_text == " ".join(shown).strip()
        assert row["col-prob"][0] == fmt.percent(item["prob_critical"])
        assert row["col-rank"][0] == str(item["rank"])
    by_tail = {r["col-tail"][0]: r for r in rows}
    assert by_tail["LOW"]["col-inspected"][0] == "2024-01-03 5.01 mm"
    assert by_tail["MID"]["col-inspected"][0] == "2024-01-05 5.10 mm, repaired"
    assert by_tail["HIGH"]["col-inspected"][0] == "none"
    assert 'href="/pages/aircraft/HIGH"' in page.text
    assert 'href="/static/style.css"' in page.text


def test_fleet_page_sorts_by_column_on_the_server(fleet: TestClient) -> None:
    by_tail = _table(fleet.get("/", params={"sort": "tail"}).text)
    assert [r["col-tail"][0] for r in by_tail] == ["HIGH", "LOW", "MID"]
    descending = _table(fleet.get("/", params={"sort": "tail", "order": "desc"}).text)
    assert [r["col-tail"][0] for r in descending] == ["MID", "LOW", "HIGH"]
    by_crack = _table(fleet.get("/", params={"sort": "crack", "order": "desc"}).text)
    cracks = [float(r["col-crack"][1]["data-value"] or "nan") for r in by_crack]
    assert cracks == sorted(cracks, reverse=True)
    # the sorted column's header links to the other direction
    assert 'href="?sort=tail&amp;order=desc"' in fleet.get("/", params={"sort": "tail"}).text
    assert fleet.get("/", params={"sort": "nonsense"}).status_code == 422


def test_overdue_inspection_is_marked(fleet: TestClient) -> None:
    # Today a year and a half after the fleet's last flights: its inspect-by dates lie in the past.
    served_settings(fleet).as_of = START.date() + timedelta(days=550)
    ranking = fleet.get("/fleet/ranking").json()
    assert ranking["as_of"] == "2025-07-04T00:00:00Z"
    due = {i["tail"] for i in ranking["items"] if i["inspect_by"] is not None}
    assert "HIGH" in due
    assert {i["tail"] for i in ranking["items"] if i["overdue"]} == due
    rows = {r["col-tail"][0]: r for r in _table(fleet.get("/").text)}
    for tail, row in rows.items():
        assert ("overdue" in row["col-inspect"][0]) == (tail in due)
    page = fleet.get("/pages/aircraft/HIGH").text
    assert "overdue" in page and 'id="as-of">2025-07-04<' in page


def test_fleet_page_without_a_model_says_what_to_do(client: TestClient) -> None:
    page = client.get("/")
    assert page.status_code == 200
    assert "No forecasts yet" in page.text
    assert "POST /models/retrain" in page.text


def test_aircraft_page_has_chart_band_inspections_and_loads(fleet: TestClient) -> None:
    page = fleet.get("/pages/aircraft/MID")
    assert page.status_code == 200
    forecast = fleet.get("/aircraft/MID/forecast").json()
    html = page.text
    assert re.search(r"<svg[^>]*>", html)
    for element in ('id="band"', 'id="forecast"', 'id="a-crit"', 'id="history"', 'id="as-of"'):
        assert element in html
    assert 'id="inspections-not-found"' in html and 'id="inspections-repair"' in html
    assert 'id="inspections-measured"' in html
    assert f'data-value="{forecast["crack_length_m"]!r}"' in html
    assert "a_crit 50.00 mm" in html
    assert "nothing found (limit 2.00 mm)" in html
    assert "5.10 mm; repaired to 4.00 mm" in html
    assert "40" in re.search(r"Flights recorded</th><td[^>]*>([^<]*)<", html).group(1)  # type: ignore[union-attr]
    assert "150.0 MPa" in html  # constant stress: mean and p95


def test_aircraft_page_errors_are_pages(fleet: TestClient) -> None:
    missing = fleet.get("/pages/aircraft/NOPE")
    assert missing.status_code == 404
    assert "Unknown tail" in missing.text and "Traceback" not in missing.text
    empty = fleet.get("/pages/aircraft/EMPTY")
    assert empty.status_code == 409
    assert "no recorded flights" in empty.text


def test_models_page_lists_versions_and_jobs(fleet: TestClient) -> None:
    html = fleet.get("/pages/models").text
    assert "v1" in html and "status-active" in html
    assert re.search(r'<progress max="1" value="1(\.0)?">', html)
    assert "retrain" in html


@pytest.mark.parametrize(("image_format", "magic"), [("svg", b"<?xml"), ("png", b"\x89PNG")])
def test_forecast_images(fleet: TestClient, image_format: str, magic: bytes) -> None:
    answer = fleet.get(f"/aircraft/HIGH/forecast.{image_format}")
    assert answer.status_code == 200
    assert (
        answer.headers["content-type"] == f"image/{'svg+xml' if image_format == 'svg' else 'png'}"
    )
    assert answer.content.startswith(magic)
    assert fleet.get(f"/aircraft/NOPE/forecast.{image_format}").status_code == 404
    assert fleet.get("/aircraft/HIGH/forecast.gif").status_code == 422


def test_ranking_image_draws_the_top_tails(fleet: TestClient) -> None:
    svg = fleet.get("/fleet/ranking.svg", params={"top": 2}).text
    assert 'id="tail-1"' in svg and 'id="tail-2"' in svg and 'id="tail-3"' not in svg
    assert 'id="band-1"' in svg
    assert "HIGH" in svg
    assert fleet.get("/fleet/ranking.png").content.startswith(b"\x89PNG")


def test_images_without_a_model_are_409(client: TestClient) -> None:
    add_tail(client, "A1", 10)
    assert client.get("/aircraft/A1/forecast.svg").status_code == 409
    assert client.get("/fleet/ranking.svg").status_code == 409


def test_docs_are_served_from_the_package(client: TestClient) -> None:
    for path, asset in (("/docs", "swagger-ui-bundle.js"), ("/redoc", "redoc.standalone.js")):
        page = client.get(path)
        assert page.status_code == 200
        assert f"/docs-assets/{asset}" in page.text
        assert "cdn" not in page.text.lower() and "fonts.googleapis" not in page.text
        script = client.get(f"/docs-assets/{asset}")
        assert script.status_code == 200 and len(script.content) > 100_000
    assert client.get("/docs-assets/swagger-ui.css").status_code == 200
    assert client.get("/static/style.css").status_code == 200
    # ReDoc's bundle asks its CDN for a logo: the served bundle asks the package's favicon instead
    bundle = client.get("/docs-assets/redoc.standalone.js").text
    assert "cdn.redoc.ly" not in bundle and '"docs-assets/favicon.png"' in bundle
    assert client.get("/docs-assets/favicon.png").status_code == 200


def test_pages_stay_out_of_the_openapi_schema(client: TestClient) -> None:
    paths = client.get("/openapi.json").json()["paths"]
    assert "/" not in paths and "/pages/models" not in paths and "/docs" not in paths
    assert "/aircraft/{tail}/forecast.{image_format}" in paths
    assert "/fleet/ranking.{image_format}" in paths
