"""The residual strength where a maintenance engineer ranks the fleet: each (tail, location)
row of GET /fleet/ranking, the export (GET /forecasts, which forecast-batch --out writes) and the
fleet page carry the residual strength at the p50 crack today and its margin over the limit
stress where the row's location gives one, the same figures as the aircraft's line (one owner:
app.services.forecasts.residual_now); rows and fleets without a limit stress are as before."""

from __future__ import annotations

import html
import io
import json
import re
from pathlib import Path

import pandas as pd
import pytest
from fastapi.testclient import TestClient

from app import commands
from app.services.ranking import export
from app.web import format as fmt
from tests.app.snapshots import served_settings
from tests.app.test_residual_strength_lines import (  # noqa: F401
    _by_hand,
    fleet,
    served_table_location,
    stored_database,
)

STRENGTH_KEYS = {"residual_strength_mpa", "criterion", "margin", "limit_stress_mpa"}


def _lines(client: TestClient, tail: str) -> dict[str, dict[str, object]]:
    body = client.get(f"/aircraft/{tail}/forecast").json()
    return {line["location"]: line for line in body["locations"]}


def test_each_ranked_row_with_a_limit_stress_carries_its_residual_strength(
    fleet: TestClient,  # noqa: F811
) -> None:
    items = fleet.get("/fleet/ranking", params={"limit": 100}).json()["items"]
    assert sorted((i["tail"], i["location"]) for i in items) == [
        ("HIGH", "default"), ("HIGH", "panel"), ("LOW", "default"), ("LOW", "panel"),
    ]  # fmt: skip
    for item in items:
        if item["location"] == "default":  # a constant F and a typed a_crit: as before
            assert "residual_strength" not in item
            continue
        strength = item["residual_strength"]
        assert set(strength) == STRENGTH_KEYS
        # the aircraft's line's figures, at the same p50 crack today
        assert strength == _lines(fleet, item["tail"])["panel"]["residual_strength"]
        want, criterion = _by_hand(item["crack_as_of_band"]["p50"])
        assert strength["residual_strength_mpa"] == pytest.approx(want, rel=1e-9)
        assert strength["criterion"] == criterion
        assert strength["margin"] == pytest.approx(want / 150.0 - 1, rel=1e-9)
        assert strength["limit_stress_mpa"] == 150.0


def test_the_export_carries_it_after_critical_crack(fleet: TestClient) -> None:  # noqa: F811
    items = fleet.get("/fleet/ranking", params={"limit": 100}).json()["items"]
    csv = pd.read_csv(io.StringIO(fleet.get("/forecasts", params={"format": "csv"}).text))
    after = export.COLUMNS.index("critical_crack_m") + 1
    located = [*export.COLUMNS[:2], "location", *export.COLUMNS[2:]]
    assert list(csv.columns) == [
        *located[: after + 1], *export.STRENGTH_COLUMNS, *located[after + 1 :]
    ]  # fmt: skip
    rows = fleet.get("/forecasts").json()
    parquet = pd.read_parquet(
        io.BytesIO(fleet.get("/forecasts", params={"format": "parquet"}).content)
    )
    assert str(parquet["residual_strength_margin"].dtype) == "float64"
    for k, (row, item) in enumerate(zip(rows, items, strict=True)):
        assert (row["tail"], row["location"]) == (item["tail"], item["location"])
        strength = item.get("residual_strength")
        if strength is None:
            assert [row[c] for c in export.STRENGTH_COLUMNS] == [None] * 4
            assert parquet["residual_strength_mpa"].isna()[k]
            continue
        assert row["limit_stress_mpa"] == strength["limit_stress_mpa"]
        assert row["residual_strength_mpa"] == strength["residual_strength_mpa"]
        assert row["residual_strength_criterion"] == strength["criterion"]
        assert row["residual_strength_margin"] == strength["margin"]
        assert parquet["residual_strength_margin"][k] == strength["margin"]


def test_forecast_batch_out_writes_the_residual_strength(
    fleet: TestClient,  # noqa: F811
    tmp_path: Path,
) -> None:
    """The batch's file (`fleetpinn forecast-batch --out`) is the export: the same strength
    columns and values, row for row."""
    out = tmp_path / "batch.json"
    outcome = commands.forecast_batch(out, settings=served_settings(fleet))
    assert outcome["status"] == "succeeded", outcome
    exported = fleet.get("/forecasts").json()
    written = json.loads(out.read_text())
    keys = ["tail", "location", *export.STRENGTH_COLUMNS]
    assert [[row[k] for k in keys] for row in written] == [
        [row[k] for k in keys] for row in exported
    ]
    assert sum(row["residual_strength_margin"] is not None for row in written) == 2


def test_the_fleet_page_shows_and_sorts_by_the_margin(fleet: TestClient) -> None:  # noqa: F811
    items = fleet.get("/fleet/ranking", params={"limit": 100}).json()["items"]
    margins = {
        i["tail"]: i["residual_strength"]["margin"] for i in items if i["location"] == "panel"
    }
    page = fleet.get("/", params={"sort": "margin"}).text
    assert 'class="col-margin sorted asc"' in page
    cells = re.findall(
        r'<tr data-tail="(\w+)".*?<td class="num col-margin"( data-value="([^"]+)")?', page, re.S
    )
    # the smallest margin first; rows without a limit stress last
    shown = [(tail, float(value)) for tail, _, value in cells if value]
    assert shown == sorted(margins.items(), key=lambda m: m[1])
    assert shown == [(t, pytest.approx(m, rel=1e-12)) for t, m in shown]
    assert [value for _, _, value in cells[len(shown) :]] == ["", ""]
    first = page[page.index('data-tail="' + shown[0][0]) :]
    cell = first[first.index('class="num col-margin"') :]
    cell = cell[: cell.index("</td>")]
    assert html.unescape(fmt.signed_percent(shown[0][1])) in html.unescape(cell)


def test_a_fleet_without_a_limit_stress_ranks_and_exports_as_before(tmp_path: Path) -> None:
    """A table location (typed a_crit) under FLEETPINN_MATERIAL, the only one with a model:
    its rows carry no residual strength and the export no margin columns; its ranking
    reads the row's last inspection at that location (where a one-location ranking of a
    location other than the default one read the default location's)."""
    with served_table_location(tmp_path) as client:
        ranking = client.get("/fleet/ranking")
        assert ranking.status_code == 200, ranking.text
        assert "residual_strength" not in ranking.text
        last = {i["tail"]: i["last_inspection"] for i in ranking.json()["items"]}
        assert last["HIGH"] is None and last["LOW"]["inspection_id"] == "L1"
        csv = pd.read_csv(io.StringIO(client.get("/forecasts", params={"format": "csv"}).text))
        # the rows name their location (not the default one), the margin columns are absent
        assert list(csv.columns) == [*export.COLUMNS[:2], "location", *export.COLUMNS[2:]]
        assert set(csv["location"]) == {"lug"}
        assert "col-margin" not in client.get("/").text
