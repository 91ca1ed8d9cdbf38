"""An upload has a time budget as a read does (request_timeout_seconds): one that cannot finish
within it is answered 503 with nothing stored, its parse, its cycles and its commit each
checking the deadline (uploads, being writes, had no time limit: four slow ones held every
request thread for minutes)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from fastapi.testclient import TestClient

from tests.app.conftest import flights, serving, settings_in


def _upload(client: TestClient, csv: str) -> object:
    return client.post("/flights/upload", files={"file": ("f.csv", csv, "text/csv")})


def test_an_upload_out_of_time_is_a_503_with_nothing_stored(tmp_path: Path) -> None:
    rows = [{"tail": f"U{i}", **f} for i in range(20) for f in flights(1000)]
    csv = pd.DataFrame(rows).to_csv(index=False)
    hurried = settings_in(tmp_path).model_copy(update={"request_timeout_seconds": 0.001})
    with serving(hurried) as client:
        answer = _upload(client, csv)
    assert answer.status_code == 503, answer.text  # type: ignore[attr-defined]
    detail = answer.json()["detail"]  # type: ignore[attr-defined]
    assert "request_timeout_seconds" in detail and "nothing was stored" in detail
    with serving(settings_in(tmp_path)) as client:
        assert client.get("/aircraft").json()["items"] == []
        events = client.get("/audit").json()["items"]
        assert [e for e in events if e["actor"] != "cli:keys"] == []  # only the keys made
        stored = _upload(client, csv)  # the same file within the default budget
        assert stored.status_code == 201, stored.text  # type: ignore[attr-defined]
        assert stored.json()["inserted"] == 20_000  # type: ignore[attr-defined]


def test_the_upload_documents_its_503(tmp_path: Path) -> None:
    with serving(settings_in(tmp_path)) as client:
        operation = client.get("/openapi.json").json()["paths"]["/flights/upload"]["post"]
    assert "nothing was stored" in operation["responses"]["503"]["description"]
