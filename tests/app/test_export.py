"""GET /forecasts: every tail in the ranking's order as CSV, Parquet or JSON."""

from __future__ import annotations

import io
import re
from datetime import timedelta

import pandas as pd
from fastapi.testclient import TestClient

from app.local_server import wait_for_job
from app.services.ranking import export
from tests.app.conftest import START, add_tail, inspect
from tests.app.snapshots import copied_for_each_test

STAMP = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ$")
# Long after the fleet's flights: the fast tails' inspect-by dates lie in the past.
LATE = {"as_of": (START + timedelta(days=400)).date().isoformat()}


def _store_fleet(client: TestClient) -> None:
    """Four tails of 40 flights at their own stress, B inspected, and the physics model active."""
    for tail, stress in (("A", 120.0), ("B", 260.0), ("C", 300.0), ("D", 90.0)):
        add_tail(client, tail, 40, stress=stress)
    inspect(client, "B", START + timedelta(days=5), 0.0052)
    job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
    assert job["status"] == "succeeded", job["error"]


stored_database, fleet = copied_for_each_test("fleet", _store_fleet)


def test_csv_json_and_parquet_hold_the_ranking_in_its_order(fleet: TestClient) -> None:
    ranking = fleet.get("/fleet/ranking", params={"limit": 100, **LATE}).json()
    order = [i["tail"] for i in ranking["items"]]
    assert order[:2] == ["C", "B"]
    answer = fleet.get("/forecasts", params={"format": "csv", **LATE})
    assert answer.headers["content-type"].startswith("text/csv")
    csv = pd.read_csv(io.StringIO(answer.text), dtype=str, keep_default_na=False)
    assert list(csv.columns) == export.COLUMNS
    assert csv["tail"].tolist() == order
    for column in export.TIME_COLUMNS:
        assert all(STAMP.match(v) for v in csv[column] if v), column
    assert csv["as_of"].unique().tolist() == [f"{LATE['as_of']}T00:00:00Z"]
    rows = fleet.get("/forecasts", params=LATE).json()
    assert [r["tail"] for r in rows] == order
    for row, item in zip(rows, ranking["items"], strict=True):
        assert row["prob_critical"] == item["prob_critical"]
        assert row["overdue"] == item["overdue"]
        assert row["inspect_by"] == item["inspect_by"]
        assert row["crack_last_flight_m"] == item["crack_length_m"]
        for q in ("p05", "p50", "p95"):
            assert row[f"crack_as_of_{q}_m"] == item["crack_as_of_band"][q]
            assert row[f"crack_at_horizon_{q}_m"] == item["crack_at_horizon_band"][q]
            assert row[f"critical_date_{q}"] == item["critical_date_quantiles"][q]
    assert any(r["overdue"] for r in rows) and not all(r["overdue"] for r in rows)
    by_tail = {r["tail"]: r for r in rows}
    assert by_tail["B"]["last_inspection_crack_m"] == 0.0052
    assert by_tail["A"]["last_inspection_id"] is None
    parquet = pd.read_parquet(
        io.BytesIO(fleet.get("/forecasts", params={"format": "parquet", **LATE}).content)
    )
    assert parquet["tail"].tolist() == order
    assert str(parquet["inspect_by"].dtype) == "datetime64[us, UTC]"
    assert parquet["overdue"].tolist() == [r["overdue"] for r in rows]


def test_export_format_and_version_are_checked(fleet: TestClient) -> None:
    assert fleet.get("/forecasts", params={"format": "xlsx"}).status_code == 422
    assert fleet.get("/forecasts", params={"model_version": 9}).status_code == 404


def test_export_without_a_model_is_409(client: TestClient) -> None:
    assert client.get("/forecasts").status_code == 409
