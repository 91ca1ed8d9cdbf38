"""CPU and wall time per request of one warm API process, requests sent one at a time.

    .venv/bin/python -c "from benchmarks.fleetdb import seed; seed('sqlite:////tmp/fleet.db', \
        aircraft_per_mix=100, years=5, train=True)"           # once: the load benchmark's fleet
    .venv/bin/python -m benchmarks.request_cost --database sqlite:////tmp/fleet.db

The load benchmark's latency is set by the CPU a request costs (32 closed-loop clients on two
cores: Little's law), and a loaded machine makes its figures noisy; this measures that cost
alone.  It serves an existing database (e.g. one benchmarks.fleetdb seeded and trained) with the
load benchmark's settings from one uvicorn process without a worker thread, sends each route
`--requests` times in turn after a warm-up and reads the server's CPU time (user + system, from
/proc) before and after.  Prints one JSON object: per route the requests, CPU ms and wall ms
per request.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import httpx

from app.local_server import start_uvicorn
from benchmarks.fleetdb import SERVICE_ENV, admin_key


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def measure(client: httpx.Client, pid: int, paths: list[str]) -> dict[str, float]:
    cpu, wall = cpu_seconds(pid), time.perf_counter()
    for path in paths:
        client.get(path).raise_for_status()
    n = len(paths)
    return {
        "requests": n,
        "cpu_ms": round(1000 * (cpu_seconds(pid) - cpu) / n, 2),
        "wall_ms": round(1000 * (time.perf_counter() - wall) / n, 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--database", required=True, help="a served fleet's database URL")
    parser.add_argument("--requests", type=int, default=300)
    args = parser.parse_args()
    env = {**SERVICE_ENV, "FLEETPINN_DATABASE_URL": args.database, "FLEETPINN_RUN_WORKER": "0"}
    with tempfile.TemporaryDirectory(prefix="fleetpinn-cost-") as folder:
        server = start_uvicorn("app.main:app", env, Path(folder) / "server.log")
        try:
            headers = admin_key(args.database)
            with httpx.Client(base_url=server.base, headers=headers, timeout=60) as client:
                items = client.get("/aircraft", params={"limit": 1000}).json()["items"]
                tails = [a["tail"] for a in items]
                forecasts = [
                    f"/aircraft/{tails[i % len(tails)]}/forecast?horizon_days=365"
                    for i in range(args.requests)
                ]
                routes = {
                    "health": ["/health"] * args.requests,
                    "forecast": forecasts,
                    "ranking": ["/fleet/ranking?limit=20"] * args.requests,
                }
                for paths in routes.values():  # warm: every tail once, the model loaded
                    measure(client, server.process.pid, sorted(set(paths)))
                result = {
                    name: measure(client, server.process.pid, paths)
                    for name, paths in routes.items()
                }
        finally:
            server.stop()
    print(json.dumps(result))


if __name__ == "__main__":
    main()
