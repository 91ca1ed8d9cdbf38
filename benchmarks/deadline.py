"""The most work one read key may ask for, on the demo fleet: does the work stop at the limit?

    .venv/bin/python -c "from benchmarks.fleetdb import seed; seed('sqlite:////tmp/fleet.db', \
        aircraft_per_mix=100, years=5, train=True)"           # once: the load benchmark's fleet
    .venv/bin/python -m benchmarks.deadline --database sqlite:////tmp/fleet.db

Issue 19 measured `GET /fleet/ranking?as_of=2400-01-01` answered 503 at 30 s while its work ran
on to 52 s at 2.9 GB.  This serves an existing database (one uvicorn process, no worker thread,
the load benchmark's settings, a 4 GiB address-space limit) and asks for: that ranking (now
refused where it enters), the farthest ranking the as-of window allows (as_of today +
max_horizon_days, horizon_days max_horizon_days: 300 tails sampled over ~20 years each) and the
farthest single forecast.  For each it reports the status, the seconds to the answer, how long
the server's CPU kept working after the answer (from /proc: the work is done once the process
stays idle), and the server's peak resident memory.  Prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from datetime import date, timedelta
from pathlib import Path

import httpx

from app.config import Settings
from app.local_server import ServiceProcess, start_uvicorn
from benchmarks.fleetdb import SERVICE_ENV, admin_key

_TICKS = os.sysconf("SC_CLK_TCK")
ADDRESS_SPACE_BYTES = 4 * 1024**3


def _cpu_s(process: ServiceProcess) -> float:
    fields = Path(f"/proc/{process.process.pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / _TICKS  # utime + stime


def _work_after(process: ServiceProcess, idle_s: float = 1.0, poll_s: float = 0.1) -> float:
    """Seconds until the process's CPU time stops growing (less than 5 % of a core over
    idle_s), counted from now."""
    started = time.monotonic()
    samples = [(started, _cpu_s(process))]
    while True:
        time.sleep(poll_s)
        now, cpu = time.monotonic(), _cpu_s(process)
        samples.append((now, cpu))
        window = [(t, c) for t, c in samples if t >= now - idle_s]
        if now - started >= idle_s and cpu - window[0][1] < 0.05 * idle_s:
            return round(max(0.0, window[0][0] - started), 1)


def _ask(
    http: httpx.Client, process: ServiceProcess, path: str, params: dict[str, str]
) -> dict[str, object]:
    started = time.monotonic()
    answer = http.get(path, params=params)
    seconds = time.monotonic() - started
    return {
        "path": path,
        "params": params,
        "status": answer.status_code,
        "answer_s": round(seconds, 2),
        "work_after_answer_s": _work_after(process),
        "detail": answer.json().get("detail") if answer.status_code != 200 else None,
        "peak_rss_mb": round(process.peak_rss_bytes() / 2**20),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--database", required=True)
    args = parser.parse_args()
    settings = Settings(
        database_url=args.database, as_of=date.fromisoformat(SERVICE_ENV["FLEETPINN_AS_OF"])
    )
    last = settings.today() + timedelta(days=settings.max_horizon_days)
    env = {**SERVICE_ENV, "FLEETPINN_DATABASE_URL": args.database, "FLEETPINN_RUN_WORKER": "0"}
    with tempfile.TemporaryDirectory(prefix="fleetpinn-deadline-") as folder:
        server = start_uvicorn(
            "app.main:app",
            env,
            Path(folder) / "server.log",
            address_space_bytes=ADDRESS_SPACE_BYTES,
        )
        try:
            headers = admin_key(args.database)
            with httpx.Client(base_url=server.base, headers=headers, timeout=120) as http:
                tail = http.get("/aircraft", params={"limit": 1}).json()["items"][0]["tail"]
                far = {"as_of": last.isoformat(), "horizon_days": str(settings.max_horizon_days)}
                asked = [
                    _ask(http, server, "/fleet/ranking", {"as_of": "2400-01-01"}),
                    _ask(http, server, "/fleet/ranking", far),
                    _ask(http, server, f"/aircraft/{tail}/forecast", far),
                ]
                health_started = time.monotonic()
                assert http.get("/health").status_code == 200
                health_s = time.monotonic() - health_started
        finally:
            server.stop()
    print(
        json.dumps(
            {
                "as_of_window": [str(settings.earliest_record_date), str(last)],
                "today": str(settings.today()),
                "time_limit_s": settings.request_timeout_seconds,
                "address_space_limit_gib": ADDRESS_SPACE_BYTES / 2**30,
                "requests": asked,
                "health_after_s": round(health_s, 3),
                "measured_on": str(date.today()),
            }
        )
    )


if __name__ == "__main__":
    main()
