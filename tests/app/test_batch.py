"""The forecast-batch job: only tails without a current forecast are computed (a current row's
values are recomputed identically), `refresh` recomputes all, and progress counts tails."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from app.cli import main
from app.config import Settings
from app.db import make_engine, make_session_factory
from app.local_server import wait_for_job
from app.services.jobs import batch
from tests.app.conftest import START, add_tail, inspect, serving, settings_in


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[TestClient, Settings]]:
    settings = settings_in(Path(tmp_path_factory.mktemp("batch")))
    with serving(settings) as client:
        for tail, stress in (("A", 120.0), ("B", 200.0), ("C", 260.0)):
            add_tail(client, tail, 40, stress=stress)
        inspect(client, "A", START + timedelta(days=5), 0.00502)
        job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
        assert job["status"] == "succeeded", job["error"]
        yield client, settings


def _batch(client: TestClient, **body: object) -> dict[str, object]:
    job = wait_for_job(client, client.post("/forecasts/batch", json=body).json()["job_id"])
    assert job["status"] == "succeeded", job["error"]
    result: dict[str, object] = job["result"]
    return result


def _bands(client: TestClient) -> dict[str, object]:
    items = client.get("/fleet/ranking", params={"limit": 10}).json()["items"]
    return {i["tail"]: (i["crack_as_of_band"], i["prob_critical"]) for i in items}


def test_only_tails_without_a_current_forecast_are_computed(
    fleet: tuple[TestClient, Settings],
) -> None:
    client, _ = fleet
    before = _bands(client)
    assert _batch(client) == {"model_version": 1, "forecasts": 3, "filled": 0, "kept": 3}
    # a new inspection drops its tail's rows: the batch computes that tail alone
    inspect(client, "B", START + timedelta(days=6), 0.0051)
    assert _batch(client) == {"model_version": 1, "forecasts": 3, "filled": 1, "kept": 2}
    after_b = _bands(client)
    assert after_b["A"] == before["A"] and after_b["C"] == before["C"]
    # recomputing every row gives the values kept: they were current
    assert _batch(client, refresh=True) == {
        "model_version": 1,
        "forecasts": 3,
        "filled": 3,
        "kept": 0,
    }
    assert _bands(client) == after_b


def test_progress_counts_tails(fleet: tuple[TestClient, Settings]) -> None:
    _, settings = fleet
    seen: list[tuple[float, str]] = []
    factory = make_session_factory(make_engine(settings.database_url))
    with factory() as session:
        batch.run_batch(
            session,
            version=None,
            settings=settings,
            progress=lambda share, stage: seen.append((share, stage)),
            refresh=True,
        )
    shares = [share for share, _ in seen]
    assert shares == sorted(shares) and shares[0] == 0.0 and shares[-1] == 1.0
    stages = [stage for _, stage in seen]
    assert stages[0] == "0 of 3 tails current; forecasting 3"
    assert "forecasting tails 3/3" in stages and stages[-1] == "done"


def test_the_command_line_shows_the_tails_on_its_bar(
    fleet: tuple[TestClient, Settings],
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
) -> None:
    _, settings = fleet
    monkeypatch.setenv("FLEETPINN_DATABASE_URL", settings.database_url)
    monkeypatch.setenv("FLEETPINN_AS_OF", str(settings.as_of))
    from app.config import get_settings

    get_settings.cache_clear()
    try:
        assert main(["forecast-batch", "--refresh", "--out", str(tmp_path / "f.csv")]) == 0
    finally:
        get_settings.cache_clear()
    printed, shown = capsys.readouterr()
    assert '"filled": 3' in printed
    assert "forecast-batch" in shown and "100%" in shown and "done" in shown
    assert (tmp_path / "f.csv").read_text().count("\n") == 4
