"""CPU an ingest costs an API process, and what it makes the next ranking and forecast cost:
two code trees on copies of one database, in one run, alternating.

    .venv/bin/python -m benchmarks.ingest_cost --setup /tmp/fleet4.db   # once, ~5 min
    .venv/bin/python -m benchmarks.ingest_cost --database sqlite:////tmp/fleet4.db \
        --baseline /path/to/a/checkout/of/main          # e.g. a `git worktree` of main

The load benchmark (benchmarks.load) loses a third of its throughput to one small ingest a
second with four locations, and on a 2-core machine shared with other work its figures move
with the load; this measures the cost itself.  Each round copies the database (one that
--setup made as benchmarks.load's `--locations 3` does: the demo fleet trained, three more
locations catalogued and inspected, every location's first retrain run), and a
child process per tree (its own PYTHONPATH: the tree's app and model) serves it in process
(FastAPI's TestClient, the load benchmark's settings, no worker thread): after a warm-up, the
same --ingests ingests of 1-4 flights to random tails, each followed by one ranking (GET
/fleet/ranking, limit 20) and the ingested tail's forecast (365 days), and one poll of the
worker's cache thread (app.worker: the bands an ingest left, tomorrow's risk); then one more
flight to the tail and four rankings sent at once (as request threads meet after a change
under the load benchmark).  The trees alternate round by round, so the machine's load falls
on both alike.  Prints one JSON object: per tree
and step the median CPU ms (the process's, all threads) and wall ms over every round, and per
step the ratio tree / baseline; the answers' digest per tree (bodies without their
computed_at: the same database and ingests must give the same answers).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import random
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

STEPS = ("ingest", "ranking", "forecast", "worker", "one more flight", "4 rankings at once")


def child(database: str, ingests: int) -> dict[str, Any]:
    """Serve the database from this process's tree and time each step of each ingest."""
    import pandas as pd
    from fastapi.testclient import TestClient

    from app.config import get_settings
    from app.db import make_engine, make_session_factory
    from app.main import create_app
    from app.worker import Worker
    from benchmarks.fleetdb import service_settings
    from tests.app.conftest import bearer, new_key

    settings = service_settings(database).model_copy(update={"run_worker": False})
    app = create_app()
    app.dependency_overrides[get_settings] = lambda: settings
    worker = Worker(make_session_factory(make_engine(database)), settings, "bench")
    digest = hashlib.sha256()
    times: dict[str, list[tuple[float, float]]] = {step: [] for step in STEPS}
    with TestClient(app) as client:
        client.headers.update(bearer(new_key(app, "admin")))
        listed = client.get("/aircraft", params={"limit": 1000}).json()["items"]
        tails = [a["tail"] for a in listed]
        last = {a["tail"]: pd.Timestamp(a["last_flown_at"]) for a in listed}
        for tail in tails[:5]:
            client.get(f"/aircraft/{tail}/forecast").raise_for_status()
        client.get("/fleet/ranking", params={"limit": 20}).raise_for_status()
        worker.warm_today()
        pick = random.Random(1)
        for n in range(ingests):
            tail = pick.choice(tails)
            body = new_flights(pick, tail, last, f"C{n}")
            steps: dict[str, Callable[[], Any]] = {
                "ingest": partial(client.post, f"/aircraft/{tail}/flights", json=body),
                "ranking": partial(client.get, "/fleet/ranking", params={"limit": 20}),
                "forecast": partial(
                    client.get, f"/aircraft/{tail}/forecast", params={"horizon_days": 365}
                ),
                "worker": partial(_cache_step, worker, settings),
                # a change again, then four request threads' rankings meeting after it
                "one more flight": partial(
                    client.post, f"/aircraft/{tail}/flights", json=_one_more(n, tail, last)
                ),
                "4 rankings at once": partial(_at_once, client, 4),
            }
            for step, call in steps.items():
                wall, cpu = time.perf_counter(), time.process_time()
                answer = call()
                times[step].append(
                    (1000 * (time.process_time() - cpu), 1000 * (time.perf_counter() - wall))
                )
                if answer is not None:
                    answer.raise_for_status()
                    if step not in ("ingest", "one more flight"):
                        digest.update(_without_computed_at(answer.json()).encode())
    return {"times": times, "digest": digest.hexdigest()[:16]}


def new_flights(
    pick: random.Random, tail: str, last: dict[str, Any], prefix: str
) -> list[dict[str, Any]]:
    """An ingest's body: 1-4 flights 6 h apart after the tail's last (`last` moves on), ids
    prefix-0, prefix-1, ..., ranges drawn from pick; benchmarks.load's ingests too."""
    import pandas as pd

    count = pick.randint(1, 4)
    start = last[tail]
    last[tail] = start + pd.Timedelta(hours=6 * count)
    return [
        {
            "flight_id": f"{prefix}-{k}",
            "flown_at": (start + pd.Timedelta(hours=6 * (k + 1))).isoformat(),
            "stress_range_mpa": pick.uniform(80.0, 160.0),
        }
        for k in range(count)
    ]


def _one_more(n: int, tail: str, last: dict[str, Any]) -> list[dict[str, Any]]:
    """One flight 6 h after the tail's last (`last` moves on)."""
    import pandas as pd

    last[tail] += pd.Timedelta(hours=6)
    return [{"flight_id": f"M{n}", "flown_at": last[tail].isoformat(), "stress_range_mpa": 120.0}]


def _at_once(client: Any, count: int) -> Any:
    """`count` rankings sent at once from as many threads; the first answer (all alike)."""
    from concurrent.futures import ThreadPoolExecutor

    ask = partial(client.get, "/fleet/ranking", params={"limit": 20})
    with ThreadPoolExecutor(count) as pool:
        answers = list(pool.map(lambda _: ask(), range(count)))
    assert len({a.content for a in answers}) == 1, "rankings at once answered differently"
    return answers[0]


def _cache_step(worker: Any, settings: Any) -> None:
    """One poll of the worker's cache thread (app.worker.Worker._keep_cache): the rows an
    ingest left without bands, then tomorrow's risk."""
    from app.services.forecasts import cache_advance

    with worker.factory() as session:
        while cache_advance.fill_pending(session, settings):
            pass
    worker.warm_today()


def _without_computed_at(body: Any) -> str:
    """The answer as canonical JSON without its computed_at fields (each run stamps its own)."""

    def strip(value: Any) -> Any:
        if isinstance(value, dict):
            return {k: strip(v) for k, v in value.items() if k != "computed_at"}
        if isinstance(value, list):
            return [strip(v) for v in value]
        return value

    return json.dumps(strip(body), sort_keys=True)


def run_tree(tree: Path, database: Path, folder: Path, ingests: int) -> dict[str, Any]:
    """One child on a copy of the database, with `tree` first on its path."""
    run = tempfile.mkdtemp(dir=folder)  # its own folder: a copy must not meet another's WAL
    copy = Path(run) / "copy.db"
    shutil.copy(database, copy)
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1"}
    found = subprocess.run(
        [sys.executable, __file__, "--child", f"sqlite:///{copy}", "--ingests", str(ingests)],
        env=env,
        cwd=tree,
        capture_output=True,
        text=True,
    )
    shutil.rmtree(run)
    if found.returncode:
        raise SystemExit(f"{tree}: {found.stderr[-3000:]}")
    return dict(json.loads(found.stdout.strip().splitlines()[-1]))


def setup(path: Path, locations: int) -> dict[str, Any]:
    """The load benchmark's fleet and locations (benchmarks.load.add_locations) in a SQLite
    file at `path`, their first retrain run by a `fleetpinn worker` beside one server."""
    import asyncio

    import aiohttp

    from app.local_server import start_service, start_worker
    from benchmarks.fleetdb import SERVICE_ENV, admin_key, seed
    from benchmarks.load import add_locations

    url = f"sqlite:///{path}"
    seeded = seed(url, aircraft_per_mix=100, years=5, train=True)
    env = {**SERVICE_ENV, "FLEETPINN_DATABASE_URL": url, "FLEETPINN_RUN_WORKER": "0"}
    worker = start_worker(env, path.with_suffix(".worker.log"))
    server = start_service(env, path.with_suffix(".server.log"))

    async def catalogue() -> Any:
        timeout = aiohttp.ClientTimeout(total=3600)
        async with aiohttp.ClientSession(
            server.base, headers=admin_key(url), timeout=timeout
        ) as session:
            async with session.get("/aircraft", params={"limit": 1000}) as answer:
                tails = [a["tail"] for a in (await answer.json())["items"]]
            return await add_locations(session, tails, locations)

    try:
        seconds, jobs = asyncio.run(catalogue())
    finally:
        server.stop()
        worker.stop()
    return {"setup": seeded, "first_retrain_of_every_location_s": round(seconds, 1), **jobs}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--database", help="sqlite:///... of a trained fleet with locations")
    parser.add_argument("--baseline", type=Path, help="a checkout to compare this tree with")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--ingests", type=int, default=10)
    parser.add_argument("--setup", type=Path, help="make the database at this path and stop")
    parser.add_argument("--locations", type=int, default=3, help="with --setup (benchmarks.load)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.setup:
        print(json.dumps(setup(args.setup.resolve(), args.locations)))
        return
    if args.child:
        print(json.dumps(child(args.child, args.ingests)), flush=True)
        os._exit(0)  # threads torch or the app's worker left may abort an orderly shutdown
    database = Path(args.database.removeprefix("sqlite:///"))
    trees = {"baseline": args.baseline.resolve(), "tree": Path(__file__).resolve().parents[1]}
    found: dict[str, list[dict[str, Any]]] = {name: [] for name in trees}
    with tempfile.TemporaryDirectory(prefix="fleetpinn-ingest-cost-") as folder:
        for _ in range(args.rounds):
            for name, tree in trees.items():
                found[name].append(run_tree(tree, database, Path(folder), args.ingests))
    out: dict[str, Any] = {"rounds": args.rounds, "ingests": args.ingests, "load": os.getloadavg()}
    for name, runs in found.items():
        out[name] = {
            "digests": sorted({run["digest"] for run in runs}),
            **{
                step: {
                    "cpu_ms": round(
                        statistics.median(c for run in runs for c, _ in run["times"][step]), 1
                    ),
                    "wall_ms": round(
                        statistics.median(w for run in runs for _, w in run["times"][step]), 1
                    ),
                }
                for step in STEPS
            },
        }
    out["ratio_cpu"] = {
        step: round(out["tree"][step]["cpu_ms"] / max(out["baseline"][step]["cpu_ms"], 1e-3), 3)
        for step in STEPS
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
