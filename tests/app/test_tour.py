"""The README's and docs/api.md's tours, run as written (real curl, the README's `fleetpinn
client` lines, real uvicorn) against a small demo fleet seeded as `make demo` seeds it: every
command answers the status its comment gives (any 2xx where none is given), and the demo's own
tails forecast exactly as before (the ranking's cracks, flight and inspection counts)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from app import commands
from app.config import Settings
from app.local_server import uvicorn_server
from model.fleet import DISCREPANCY_20PCT, FleetConfig, generate_fleet
from model.records import write_table
from tests.app.conftest import bearer

ROOT = Path(__file__).parents[2]
FLEET = {"aircraft_per_mix": 34, "years": 1}  # 102 tails N001..N102: N001 and N100 exist
# The demo's settings, with budgets a test can afford.
FAST = {
    "FLEETPINN_LBFGS_ITERATIONS": "10",
    "FLEETPINN_POSTERIOR_RESTARTS": "1",
    "FLEETPINN_FORECAST_SAMPLES": "20",
    "FLEETPINN_WORKER_POLL_SECONDS": "0.05",
}
CLIENT = "$F client "  # the README's client lines: F is this tree's `fleetpinn`
_STATUS = re.compile(r"#\s+(\d{3})\b")
_FINISHED = ("succeeded", "failed", "cancelled")


def _split(line: str, quoted: str | None) -> tuple[str, str, str | None]:
    """(code, comment, quote still open at the end) of one shell line, `quoted` the quote open
    at its start: a # outside quotes, after a blank, starts the comment."""
    for i, char in enumerate(line):
        if quoted:
            quoted = None if char == quoted else quoted
        elif char in "'\"":
            quoted = char
        elif char == "#" and (i == 0 or line[i - 1] in " \t"):
            return line[:i], line[i:], None
    return line, "", quoted


def tour(text: str, starts: tuple[str, ...] = ("curl ",)) -> list[tuple[str, int | None]]:
    """The curl commands (and the commands of `starts`) of the ```bash blocks in order, each
    with the status its comment (on its last line, or the comment line right after it) gives."""
    found: list[tuple[str, int | None]] = []
    for block in re.findall(r"```bash\n(.*?)```", text, re.S):
        lines = [line.strip() for line in block.splitlines()]
        i = 0
        while i < len(lines):
            if not lines[i].startswith(starts):
                i += 1
                continue
            parts: list[str] = []
            quoted: str | None = None
            while True:
                code, comment, quoted = _split(lines[i], quoted)
                parts.append(lines[i])
                i += 1
                if not quoted and not code.rstrip().endswith("\\"):
                    break
            status = _STATUS.match(comment)
            if status is None and i < len(lines) and lines[i].startswith("#"):
                status = _STATUS.match(lines[i])
            found.append(("\n".join(parts), None if status is None else int(status.group(1))))
    return found


def test_the_tour_parser_reads_commands_and_statuses() -> None:
    text = """```bash
curl -s localhost:8000/a -H "$AUTH"      # 201 created
curl -s localhost:8000/b -d '[
  {"x": 1}
]'
# 422 {"detail": …}
fleetpinn keys list
curl -s localhost:8000/c \\
     -X POST                             # the tour's # 200 is not a status
```"""
    assert tour(text) == [
        ('curl -s localhost:8000/a -H "$AUTH"      # 201 created', 201),
        ("curl -s localhost:8000/b -d '[\n{\"x\": 1}\n]'", 422),
        (
            "curl -s localhost:8000/c \\\n-X POST                             # the tour's # 200 is not a status",
            None,
        ),
    ]


def test_the_tours_header_counts_its_requests() -> None:
    """docs/api.md's opening says how many requests its tour is, and how many of them its end;
    both are the commands test_the_tour_runs_on_the_demo_and_leaves_its_fleet_as_it_was runs."""
    text = (ROOT / "docs/api.md").read_text()
    said = re.search(r"The tour\s+is (\d+) requests, the last (\d+) at its end", text)
    assert said, "docs/api.md's opening no longer counts the tour's requests"
    head, end = text.split("## End of the tour")
    assert (int(said.group(1)), int(said.group(2))) == (len(tour(text)), len(tour(end)))
    assert len(tour(head)) + len(tour(end)) == len(tour(text))


def _run(command: str, base: str, env: dict[str, str], cwd: Path) -> tuple[int, str]:
    """One command through bash, as a reader pastes it; curl reports the status on stderr, the
    client (`$F client`) its exit status (0 read as 200)."""
    if command.startswith(CLIENT):
        client_env = {**env, "FLEETPINN_URL": base}
        done = subprocess.run(
            ["bash", "-c", command], env=client_env, cwd=cwd, capture_output=True, text=True
        )
        return (200 if done.returncode == 0 else done.returncode), done.stdout + done.stderr
    script = 'curl() { command curl -w "%{stderr}%{http_code}" "$@"; }\n' + command.replace(
        "localhost:8000", base.removeprefix("http://")
    )
    done = subprocess.run(
        ["bash", "-c", script], env=env, cwd=cwd, capture_output=True, text=True, timeout=120
    )
    return int(done.stderr.strip()[-3:]), done.stdout


def _state(client: httpx.Client) -> dict[str, tuple[float, int, int]]:
    """Each tail's crack now at the default location (its active version) and its flight and
    inspection counts (the tour catalogues a location, which its retrain gives an analysis:
    the ranking then lists a row per tail and location)."""
    items = client.get("/fleet/ranking", params={"limit": 1000}).json()["items"]
    ranking = [i for i in items if i.get("location", "default") == "default"]
    counts = {a["tail"]: a for a in client.get("/aircraft", params={"limit": 1000}).json()["items"]}
    return {
        i["tail"]: (
            i["crack_length_m"],
            counts[i["tail"]]["flight_count"],
            counts[i["tail"]]["inspection_count"],
        )
        for i in ranking
    }


@pytest.mark.skipif(shutil.which("curl") is None, reason="curl is not installed")
def test_the_tour_runs_on_the_demo_and_leaves_its_fleet_as_it_was(tmp_path: Path) -> None:
    database = Settings(database_url=f"sqlite:///{tmp_path / 'demo.db'}")
    fast = database.model_copy(
        update={"lbfgs_iterations": 10, "posterior_restarts": 1, "forecast_samples": 20}
    )
    commands.seed_demo(
        **FLEET, inspected=6, discrepancy=DISCREPANCY_20PCT, settings=database
    )  # as `fleetpinn seed-demo` does, on a smaller fleet
    assert commands.retrain({}, settings=fast)["status"] == "succeeded"
    key = commands.create_key("admin", "demo", replace=True, settings=database).key
    (tmp_path / "demo").mkdir()
    flights = generate_fleet(FleetConfig(**FLEET)).flights_frame()
    write_table(flights, tmp_path / "demo" / "flights.csv")  # what `fleetpinn demo` writes
    text, end = (ROOT / "docs/api.md").read_text().split("## End of the tour")
    steps = [*tour((ROOT / "README.md").read_text(), ("curl ", CLIENT)), *tour(text)]
    cleanup = tour(end)
    assert len(steps) > 40 and cleanup
    (tmp_path / "tour").mkdir()
    env = {
        "TOUR": str(tmp_path / "tour"),
        "PATH": "/usr/bin:/bin",
        "KEY": key,
        "AUTH": f"Authorization: Bearer {key}",
        "JSON": "content-type: application/json",
        "JOB": "",
        "F": str(Path(sys.executable).with_name("fleetpinn")),
        "FLEETPINN_API_KEY": key,  # the README's client block exports it
        "PYTHONPATH": str(ROOT),
    }
    server_env = {"FLEETPINN_DATABASE_URL": database.database_url, "OMP_NUM_THREADS": "1", **FAST}
    with (
        uvicorn_server("app.main:app", server_env, log=tmp_path / "server.log") as base,
        httpx.Client(base_url=base, headers=bearer(key), timeout=60) as client,
    ):
        before = _state(client)
        assert client.get("/ready").json()["model_version"] == 1
        flagged = None
        for command, expected in [*steps, *cleanup]:
            if flagged is None and (command, expected) == cleanup[0]:
                flagged = client.get("/aircraft/N900/inspections").json()
            status, out = _run(command, base, env, tmp_path)
            deadline = time.monotonic() + 300
            while "/jobs/$JOB" in command and "-X POST" not in command:
                if json.loads(out)["status"] in _FINISHED or time.monotonic() > deadline:
                    break  # a reader asks again until the job has finished
                time.sleep(0.2)
                status, out = _run(command, base, env, tmp_path)
            if expected is None:
                assert 200 <= status < 300, (command, status, out[:500])
            else:
                assert status == expected, (command, status, out[:500])
            answer = json.loads(out) if out.startswith("{") else {}
            if "job_id" in answer and command.startswith("curl -s -X POST"):
                env["JOB"] = answer["job_id"]
        after = _state(client)
        assert client.get("/ready").json()["model_version"] == 1
        assert client.get("/aircraft/N900").status_code == 404  # removed at the tour's end
    assert set(after) == set(before)
    for tail, (crack, flights_count, inspections) in before.items():
        assert after[tail][1:] == (flights_count, inspections), tail
        assert after[tail][0] == pytest.approx(crack, rel=1e-12), tail
    # the tour's records agree with the fleet: nothing of them is flagged once I2 is corrected
    assert flagged is not None
    assert [i["flagged"] for i in flagged] == [False] * len(flagged) and len(flagged) == 5
    # the tour's files went to $TOUR, none into the working directory
    assert (tmp_path / "tour" / "model.pt").stat().st_size > 0
    assert not list(tmp_path.glob("*.svg")) and not (tmp_path / "model.pt").exists()
