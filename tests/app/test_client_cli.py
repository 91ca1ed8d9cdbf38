"""`fleetpinn client` against a real uvicorn process (tests.app.test_e2e's server) over HTTP."""

from __future__ import annotations

import io
import json
import re
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from datetime import timedelta
from http.server import BaseHTTPRequestHandler, HTTPServer
from pathlib import Path
from typing import ClassVar

import httpx
import pandas as pd
import pytest

from app.cli import main
from app.services.ranking import export
from app.web import format as fmt
from tests.app.conftest import SQLITE_ONLY_SERVER, START, flights

# server: the real uvicorn (and the database it serves)
from tests.app.test_e2e import server, server_database, server_log  # noqa: F401

pytestmark = SQLITE_ONLY_SERVER

STRESS = {"K1": 110.0, "K2": 180.0, "K3": 300.0}


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("client")
    rows = [{"tail": t, **f} for t, s in STRESS.items() for f in flights(40, stress=s)]
    pd.DataFrame(rows).to_csv(folder / "flights.csv", index=False)
    inspections = pd.DataFrame(
        [
            {
                "tail": "K2",
                "inspection_id": "I1",
                "inspected_at": START + timedelta(days=5),
                "crack_length_m": 0.0052,
            },
            {
                "tail": "K3",
                "inspection_id": "I2",
                "inspected_at": START + timedelta(days=6),
                "crack_length_m": 0.0061,
            },
        ]
    )
    inspections.to_csv(folder / "inspections.csv", index=False)
    return folder / "flights.csv", folder / "inspections.csv"


def client(url: str, *argv: str) -> int:
    return main(["client", "--url", url, *argv])


@pytest.fixture(autouse=True)
def api_key(server: httpx.Client, monkeypatch: pytest.MonkeyPatch) -> str:  # noqa: F811
    """The server's admin key, where the client reads it (FLEETPINN_API_KEY)."""
    key = server.headers["authorization"].removeprefix("Bearer ")
    monkeypatch.setenv("FLEETPINN_API_KEY", key)
    return key


def test_upload_inspect_retrain_and_read_the_fleet(
    server: httpx.Client,  # noqa: F811
    files: tuple[Path, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    url = str(server.base_url).rstrip("/")
    flights_csv, inspections_csv = files
    assert client(url, "upload", str(flights_csv), "--json") == 0
    printed, shown = capsys.readouterr()
    assert json.loads(printed) == {"inserted": 120, "duplicates": 0, "aircraft_created": 3}
    assert "upload flights.csv" in shown and "stored" in shown  # the bar, on stderr
    assert client(url, "inspect", "--file", str(inspections_csv), "--json") == 0
    inspected = json.loads(capsys.readouterr().out)
    assert (inspected["inserted"], inspected["duplicates"]) == (2, 0)
    assert [a["inspection_id"] for a in inspected["assessments"]] == ["I1", "I2"]
    assert client(url, "retrain", "--wait", "--json") == 0
    printed, shown = capsys.readouterr()
    job = json.loads(printed)
    assert (job["status"], job["stage"], job["model_version"]) == ("succeeded", "done", 1)
    assert "retrain" in shown and "100%" in shown and "done" in shown

    assert client(url, "forecast", "K3", "--json", "--horizon-days", "30") == 0
    served = server.get("/aircraft/K3/forecast", params={"horizon_days": 30}).json()
    assert json.loads(capsys.readouterr().out) == served
    assert client(url, "forecast", "K3", "--horizon-days", "30") == 0
    table = capsys.readouterr().out
    assert "crack at last flight" in table and fmt.mm(served["crack_length_m"]) in table

    assert client(url, "ranking", "--csv") == 0
    rows = pd.read_csv(io.StringIO(capsys.readouterr().out))
    ranking = server.get("/fleet/ranking").json()
    assert rows["tail"].tolist() == [i["tail"] for i in ranking["items"]] == ["K3", "K2", "K1"]
    assert rows["crack_as_of_p50_m"].tolist() == [
        i["crack_as_of_band"]["p50"] for i in ranking["items"]
    ]
    assert client(url, "ranking") == 0
    assert "K3" in capsys.readouterr().out

    out = tmp_path / "fleet.parquet"
    assert client(url, "export", "--out", str(out)) == 0
    frame = pd.read_parquet(out)
    assert list(frame.columns) == export.COLUMNS
    assert frame["tail"].tolist() == ["K3", "K2", "K1"]
    assert client(url, "export", "--format", "csv") == 0
    assert capsys.readouterr().out.splitlines()[0] == ",".join(export.COLUMNS)

    assert client(url, "jobs") == 0
    assert job["job_id"] in capsys.readouterr().out


def test_a_flagged_inspection_says_so_with_its_z(
    server: httpx.Client,  # noqa: F811
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Not only "inserted 1": an inspection far from its tail's forecast is stored but flagged,
    and the client says so with its z (the model is the one the first test trained)."""
    url = str(server.base_url).rstrip("/")
    at = (START + timedelta(days=9)).isoformat()
    argv = ["inspect", "K1", "--id", "ODD", "--at", at, "--crack-m", "0.03"]
    assert client(url, *argv) == 0
    printed = capsys.readouterr().out
    stored = server.get("/aircraft/K1/inspections/ODD").json()
    assert stored["flagged"] is True
    assert f"FLAGGED K1 ODD: z = {stored['forecast_z']:+.1f} against the forecast of" in printed
    assert fmt.mm(stored["forecast_crack_m"]) in printed
    assert re.search(r"flagged\s+│\s+1\s+│", printed)


def test_bad_input_is_one_line_and_exit_2(
    server: httpx.Client,  # noqa: F811
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    url = str(server.base_url).rstrip("/")
    bad = tmp_path / "bad.csv"
    bad.write_text("tail,flight_id,flown_at,stress_range_mpa\nZ1,F1,2024-01-01T00:00:00Z,-3\n")
    cases = [
        (["upload", str(bad)], "bad.csv row 1, column stress_range_mpa: must be > 0, got -3"),
        (["upload", str(tmp_path / "none.csv")], "none.csv: no such file"),
        (["forecast", "NOPE"], "404 from GET /aircraft/NOPE/forecast: unknown"),
        (
            ["forecast", "NOPE", "--location", "wing"],
            "404 from GET /aircraft/NOPE/locations/wing/forecast: unknown",
        ),
        (["export", "--format", "parquet"], "give --out FILE.parquet"),
        (["inspect", "--file", str(bad)], "bad.csv"),  # a flights file is no inspections file
        (
            ["inspect", "K1", "--id", "X1", "--at", "tomorrow", "--crack-m", "0.01"],
            "--at: not an ISO 8601 date or time: 'tomorrow'",
        ),
        (["inspect", "K1", "--id", "X1", "--at", "2024-01-02"], "--crack-m is needed"),
    ]
    for argv, message in cases:
        assert client(url, *argv) == 2, argv
        shown = capsys.readouterr().err.strip().splitlines()
        assert message in shown[-1], shown
        assert not any("Traceback" in line for line in shown)


def test_an_unreachable_service_is_one_line_and_exit_1(capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket() as s:  # a port nothing listens on once closed
        s.bind(("127.0.0.1", 0))
        url = f"http://127.0.0.1:{s.getsockname()[1]}"
    assert client(url, "jobs") == 1
    assert capsys.readouterr().err.startswith(
        f"fleetpinn client: error: cannot reach the service at {url}"
    )


class _Recorder(BaseHTTPRequestHandler):
    """Answers every GET with an empty job list and keeps the Authorization header it got."""

    seen: ClassVar[list[str | None]] = []

    def do_GET(self) -> None:
        type(self).seen.append(self.headers.get("authorization"))
        body = b"[]"
        self.send_response(200)
        self.send_header("content-type", "application/json")
        self.send_header("content-length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *_: object) -> None:
        pass


@pytest.fixture
def recorder() -> Iterator[str]:
    http = HTTPServer(("127.0.0.1", 0), _Recorder)
    thread = threading.Thread(target=http.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{http.server_address[1]}"
    finally:
        http.shutdown()
        http.server_close()


def test_the_api_key_goes_as_a_bearer_token(
    recorder: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    _Recorder.seen.clear()
    monkeypatch.setenv("FLEETPINN_API_KEY", "s3cret")
    assert client(recorder, "jobs", "--json") == 0
    monkeypatch.delenv("FLEETPINN_API_KEY")
    assert client(recorder, "jobs", "--json") == 0
    assert _Recorder.seen == ["Bearer s3cret", None]
    assert capsys.readouterr().out.split() == ["[]", "[]"]


_REFUSED_JOB = {
    "job_id": "J1",
    "kind": "retrain",
    "status": "succeeded",
    "progress": 1.0,
    "stage": "done",
    "model_version": 2,
    "outcome": "refused",
    "outcome_reason": "refused by the promotion gate: candidate 43.3 % vs active 0.0092 %",
    "metrics": {
        "gate": {
            "passed": False,
            "reason": "candidate 43.3 % vs active 0.0092 %",
            "active_version": 1,
            "culprits": [
                {
                    "inspection": "T3/I-7",
                    "crack_length_m": 0.0123,
                    "candidate_error_pct": 152.25,
                    "active_error_pct": 0.5,
                },
                "T4 I-9",
            ],
            "flagged": [{"inspection": "T5/I-2", "z": 11.6}],
        }
    },
    "finished_at": "2026-11-20T10:00:00Z",
    "error": None,
}
# a forecast far larger than a pipe holds: the reader is gone before the client is done
_BIG_FORECAST = {
    "tail": "N100",
    "trajectory": [{"day": i, "crack_length_m": 0.01} for i in range(50_000)],
}


class _Service(BaseHTTPRequestHandler):
    """A service that refused a retrain and serves one very long forecast."""

    def _send(self, value: object) -> None:
        body = json.dumps(value).encode()
        self.send_response(200)
        self.send_header("content-type", "application/json")
        self.send_header("content-length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def do_GET(self) -> None:
        answers = {
            "/jobs/J1": _REFUSED_JOB,
            "/jobs": [_REFUSED_JOB],
            "/aircraft/N100/forecast": _BIG_FORECAST,
        }
        self._send(answers[self.path.split("?")[0]])

    def do_POST(self) -> None:
        self.rfile.read(int(self.headers.get("content-length") or 0))
        self._send({"job_id": "J1", "status": "queued"})

    def log_message(self, *_: object) -> None:
        pass


@pytest.fixture
def service() -> Iterator[str]:
    http = HTTPServer(("127.0.0.1", 0), _Service)
    thread = threading.Thread(target=http.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{http.server_address[1]}"
    finally:
        http.shutdown()
        http.server_close()


def test_a_refused_retrain_reads_refused_with_its_reason_and_culprits(
    service: str, capsys: pytest.CaptureFixture[str]
) -> None:
    for argv in (["retrain", "--wait"], ["jobs", "J1"]):
        assert client(service, *argv) == 0
        printed = " ".join(capsys.readouterr().out.split())
        assert "refused by the promotion gate: candidate 43.3 % vs active 0.0092 %" in printed
        assert "retrain REFUSED: model v2 is stored as a candidate and v1 stays active" in printed
        assert (
            "inspections that drove the refusal (2): T3/I-7: crack_length_m 0.0123, "
            "candidate_error_pct 152.2, active_error_pct 0.5 T4 I-9" in printed
        )
        assert "flagged inspections it trained on (1): T5/I-2: z 11.6" in printed
    assert client(service, "jobs") == 0
    listed = " ".join(capsys.readouterr().out.split())
    assert "refused by the promotion gate" in listed and "succeeded" in listed
    assert client(service, "jobs", "--csv") == 0
    rows = pd.read_csv(io.StringIO(capsys.readouterr().out))
    assert rows["outcome"].tolist() == [
        "refused by the promotion gate: candidate 43.3 % vs active 0.0092 %"
    ]


def test_the_url_goes_before_or_after_the_action(
    recorder: str, capsys: pytest.CaptureFixture[str]
) -> None:
    _Recorder.seen.clear()
    assert main(["client", "jobs", "--url", recorder, "--json"]) == 0
    assert main(["client", "jobs", "--json", "--url", recorder, "--timeout", "5"]) == 0
    assert main(["client", "--url", "http://127.0.0.1:9", "jobs", "--url", recorder]) == 0
    assert len(_Recorder.seen) == 3
    capsys.readouterr()


def test_a_reader_that_goes_away_ends_no_traceback(service: str) -> None:
    """`fleetpinn client forecast N100 --json | head -1`: head leaves after one line."""
    process = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys; from app.cli import main; sys.exit(main())",
            "client",
            "forecast",
            "N100",
            "--json",
            "--url",
            service,
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    assert process.stdout is not None and process.stderr is not None
    assert process.stdout.readline().strip() == b"{"
    process.stdout.close()
    shown = process.stderr.read().decode()
    assert process.wait(timeout=60) == 141, shown
    assert "Traceback" not in shown and "BrokenPipeError" not in shown, shown
