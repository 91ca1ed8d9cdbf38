"""Server time of the pages and images on a stored fleet (goal: `/` with 300 tails < 300 ms).

    export FLEETPINN_DATABASE_URL=sqlite:////tmp/demo/fleetpinn.db
    fleetpinn migrate && fleetpinn seed-demo && fleetpinn retrain     # once, ~2-3 min
    .venv/bin/python -m benchmarks.pages [--requests 20]

Starts a real uvicorn on that database (no worker) serving the app wrapped in one middleware
that reports the time from the request's arrival to its response's headers (the handler, the
template or chart rendering included) in a Server-Timing header; the client's wall time over
loopback is printed next to it.  The first request of each path is reported apart (cold: the
ranking fills any missing cache there, a chart's first render loads matplotlib's fonts).  Prints
one JSON object: per path, cold ms and the median / p95 / max of the warm requests.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from collections.abc import Awaitable, Callable
from typing import Any

import httpx
from fastapi import FastAPI, Request, Response

from app.commands import create_key
from app.config import Settings
from app.local_server import uvicorn_server

GOAL_MS = 300.0


def timed_app() -> FastAPI:
    """app.main's application reporting its own time per request (Server-Timing: app;dur=ms)."""
    from app.main import create_app

    app = create_app()

    @app.middleware("http")
    async def server_timing(
        request: Request, call_next: Callable[[Request], Awaitable[Response]]
    ) -> Response:
        started = time.perf_counter()
        response = await call_next(request)
        response.headers["Server-Timing"] = f"app;dur={(time.perf_counter() - started) * 1e3:.2f}"
        return response

    return app


def _server_ms(response: httpx.Response) -> float:
    return float(response.headers["server-timing"].split("dur=")[1])


def _measure(client: httpx.Client, path: str, requests: int) -> dict[str, Any]:
    def one() -> tuple[float, float]:
        started = time.perf_counter()
        response = client.get(path)
        wall = (time.perf_counter() - started) * 1e3
        response.raise_for_status()
        return _server_ms(response), wall

    cold_server, cold_wall = one()
    warm = [one() for _ in range(requests)]
    server = sorted(s for s, _ in warm)
    wall = sorted(w for _, w in warm)
    p95 = max(0, round(0.95 * len(server)) - 1)
    return {
        "cold_server_ms": round(cold_server, 1),
        "cold_wall_ms": round(cold_wall, 1),
        "server_ms": {
            "median": round(statistics.median(server), 1),
            "p95": round(server[p95], 1),
            "max": round(server[-1], 1),
        },
        "wall_ms_median": round(statistics.median(wall), 1),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--database-url", default=os.environ.get("FLEETPINN_DATABASE_URL"))
    parser.add_argument("--requests", type=int, default=20, help="warm requests per path")
    args = parser.parse_args()
    if not args.database_url:
        parser.error("--database-url or FLEETPINN_DATABASE_URL: a database with a trained fleet")
    env = {
        "FLEETPINN_DATABASE_URL": args.database_url,
        "FLEETPINN_RUN_WORKER": "false",
        "OMP_NUM_THREADS": os.environ.get("OMP_NUM_THREADS", "1"),
    }
    quiet = ("--log-level", "warning")
    key = create_key(
        "read",
        "benchmark-pages",
        replace=True,
        settings=Settings(database_url=args.database_url),
    ).key
    headers = {"Authorization": f"Bearer {key}"}
    with (
        uvicorn_server("benchmarks.pages:timed_app", env, factory=True, uvicorn_args=quiet) as base,
        httpx.Client(base_url=base, timeout=120, headers=headers) as client,
    ):
        ranking = client.get("/fleet/ranking", params={"limit": 1}).json()
        top = ranking["items"][0]["tail"]
        total = ranking["total"]
        paths = [
            "/",
            "/?sort=inspect",
            f"/fleet/ranking?limit={total}",
            f"/pages/aircraft/{top}",
            f"/aircraft/{top}/forecast.svg",
            f"/aircraft/{top}/forecast.png",
            "/fleet/ranking.svg?top=10",
            "/pages/models",
        ]
        results = {path: _measure(client, path, args.requests) for path in paths}
    fleet = results["/"]["server_ms"]["median"]
    print(
        json.dumps(
            {
                "tails": total,
                "requests_per_path": args.requests,
                "paths": results,
                "goal": f"/ median server time < {GOAL_MS:.0f} ms",
                "goal_met": fleet < GOAL_MS,
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
