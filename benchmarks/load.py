"""Mixed load on one real server over loopback while a retrain runs: errors and latency per route.

    .venv/bin/python -m benchmarks.load                        # 300 x 7,300 flights, SQLite
    .venv/bin/python -m benchmarks.load --backend postgresql   # the same on PostgreSQL
    .venv/bin/python -m benchmarks.load --aircraft-per-mix 5 --years 1 --seconds 10   # a quick look
    .venv/bin/python -m benchmarks.load --locations 3            # 4 control points (issue 20)
    .venv/bin/python -m benchmarks.load --locations 3 --settle-s 90   # a service up a while
    .venv/bin/python -m benchmarks.load --no-retrain             # reads and ingests alone
    .venv/bin/python -m benchmarks.load --keep-seeded /tmp/fleet.db   # keep the seeded file
    .venv/bin/python -m benchmarks.load --seeded /tmp/fleet.db   # start from a copy of it

Stores the demo fleet and trains the default model (benchmarks.fleetdb), then serves it as a
deployment would on a 2-core box: `fleetpinn serve --processes 2` (each process on its own
socket, app.reuse_port) with the service's defaults and no worker thread, beside one `fleetpinn worker` process whose jobs run
at a lower CPU priority (FLEETPINN_WORKER_NICE; --worker thread: the API's own worker thread, as
`make demo` runs).  It queues a retrain of the default model (none with --no-retrain: what the
retrain's CPU costs the reads, apart) and, at once, lets --clients
concurrent clients (asyncio + aiohttp, one process) send requests back to back for --seconds:
single-aircraft forecasts (GET, 75 %) and the fleet ranking (GET, 25 %), while one more client
sends small ingests of 1-4 new flights to a random tail at --ingests-per-s (POST; the ingest
advances the tail's cached state over them, its bands and tomorrow's risk included, in its own
transaction: app.services.forecasts.cache_advance).  The clients are aiohttp's (its HTTP parser is
compiled): with httpx (pure Python) the generator itself held half a core, reading each 62 KB
forecast, and the latency it measured was mostly its own queue (benchmarks/RESULTS.md).  The default rate, 1 a second, is 70x the flights
the demo fleet flies (300 tails x 4 a day).  An error is any answer other than 2xx, or no
answer.  Each API process makes the tails' forecasts before they are asked (app.services.
forecasts.answers_ahead: after each location's first version is activated, and after each ingest), as a
deployment serves; --no-answers-ahead leaves each to its first request in each process, as
before session 16.  Prints one JSON object: per route the requests, errors, p50/p99/max ms
(forecasts also apart: each tail's first two, where an API process made its kept answer when
none was made ahead, and the later ones); the retrain's outcome and duration; requests per
second; the API processes' CPU per request over the load (api_cpu_ms_per_request: a route's
cost that other work on a shared machine moves less than it moves the latency) and the load
average (1, 5, 15 min) before and after.  --settle-s waits that long between the service's
start (with --locations, the end of the first retrain of every location) and the load, as for
a service up a while: its API processes' answers made ahead and its worker's risk of the day
done (without it the load starts while they are made).  --seeded starts from a copy of a SQLite
file that --keep-seeded kept (seeded and trained, before any load): runs to compare, e.g.
before and after a change, start from the same database without seeding and training again.
Goals (issues 9, 42): 0 errors; forecast and ranking p99 <= 200 ms on the 2-core machine, and
the ingests at their rate.
"""

from __future__ import annotations

import argparse
import asyncio
import itertools
import json
import os
import random
import shutil
import tempfile
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import aiohttp
import numpy as np
import pandas as pd

from app.local_server import start_service, start_worker
from benchmarks.fleetdb import SERVICE_ENV, admin_key, database, seed
from benchmarks.ingest_cost import new_flights

MIX = (("forecast", 0.75), ("ranking", 0.25))
# catalogue entries --locations adds beside the default one (issue 20's control points: their
# own stress transfer factor, each inspected where the default location is)
PLACES = (("wing-splice", 1.08), ("lap-joint", 0.92), ("bulkhead", 1.05))


class Recorder:
    """Each route's latencies and errors.  A forecast among its tail's first two also counts
    apart: in either API process the first forecast of a tail made its kept answer (~17 ms of
    CPU with four locations, app.services.forecasts.forecast_answers) where none was made ahead
    (--no-answers-ahead), and the 600 of them that a 300-tail fleet takes were most of the
    slowest forecasts (benchmarks/RESULTS.md); made ahead, they should look like the later."""

    def __init__(self) -> None:
        self.latency_ms: dict[str, list[float]] = defaultdict(list)
        self.errors: dict[str, list[str]] = defaultdict(list)
        self.asked: dict[str, int] = defaultdict(int)  # requests sent per path
        self.apart: dict[str, list[float]] = defaultdict(list)  # forecasts: first two, later

    async def send(
        self, route: str, session: aiohttp.ClientSession, method: str, path: str, **kwargs: Any
    ) -> None:
        """One request, timed to the end of its body."""
        self.asked[path] += 1
        among_first_two = self.asked[path] <= 2
        started = time.perf_counter()
        try:
            async with session.request(method, path, **kwargs) as answer:
                body = await answer.read()
                failed = None if answer.ok else f"{answer.status}: {body[:200]!r}"
        except aiohttp.ClientError as exc:
            failed = f"{type(exc).__name__}: {exc}"
        latency = 1000 * (time.perf_counter() - started)
        self.latency_ms[route].append(latency)
        if route == "forecast":
            self.apart["a tail's first two" if among_first_two else "later"].append(latency)
        if failed:
            self.errors[route].append(failed)

    def summary(self) -> dict[str, Any]:
        out = {}
        for route, values in sorted(self.latency_ms.items()):
            ms = np.array(values)
            out[route] = {
                "requests": len(ms),
                "errors": len(self.errors[route]),
                "p50_ms": round(float(np.percentile(ms, 50)), 1),
                "p99_ms": round(float(np.percentile(ms, 99)), 1),
                "max_ms": round(float(ms.max()), 1),
                "first_errors": sorted(set(self.errors[route]))[:3],
            }
        if "forecast" in out:
            out["forecast"]["apart"] = {
                name: {
                    "requests": len(values),
                    "p50_ms": round(float(np.percentile(values, 50)), 1),
                    "p99_ms": round(float(np.percentile(values, 99)), 1),
                }
                for name, values in sorted(self.apart.items())
            }
        return out


async def client_loop(
    session: aiohttp.ClientSession, recorder: Recorder, tails: list[str], number: int, until: float
) -> None:
    """Forecasts and rankings back to back."""
    pick = random.Random(number)
    routes = [name for name, _ in MIX]
    weights = [share for _, share in MIX]
    while time.monotonic() < until:
        route = pick.choices(routes, weights)[0]
        if route == "forecast":
            path, params = f"/aircraft/{pick.choice(tails)}/forecast", {"horizon_days": 365}
        else:
            path, params = "/fleet/ranking", {"limit": 20}
        await recorder.send(route, session, "GET", path, params=params)


async def ingest_loop(
    session: aiohttp.ClientSession,
    recorder: Recorder,
    last_flown: dict[str, pd.Timestamp],
    per_s: float,
    until: float,
) -> None:
    """Small ingests at a fixed rate: 1-4 new flights after a random tail's last one."""
    pick = random.Random(-1)
    sent = 0
    while per_s > 0 and time.monotonic() < until:
        tail = pick.choice(sorted(last_flown))
        body = new_flights(pick, tail, last_flown, f"L{sent}")
        sent += 1
        due = time.monotonic() + 1.0 / per_s
        await recorder.send("ingest", session, "POST", f"/aircraft/{tail}/flights", json=body)
        await asyncio.sleep(max(0.0, due - time.monotonic()))


async def wait_for_jobs(session: aiohttp.ClientSession, job_ids: list[str]) -> list[dict[str, Any]]:
    """Each job's final record (GET /jobs/{id}), polled until none is queued or running."""
    while True:
        found = []
        for job_id in job_ids:
            async with session.get(f"/jobs/{job_id}") as answer:
                found.append(await answer.json())
        if not {"queued", "running"} & {job["status"] for job in found}:
            return found
        await asyncio.sleep(1.0)


async def add_locations(
    session: aiohttp.ClientSession, tails: list[str], count: int
) -> tuple[float, dict[str, dict[str, Any]]]:
    """`count` of PLACES catalogued, every default inspection copied to each (the same crack,
    as a programme inspecting every control point at once), and a first retrain of every
    location run to its end, so the load's forecasts summarise them all; returns its seconds
    and each location's job: its outcome (activated, refused, ...) and why."""
    for name, factor in PLACES[:count]:
        async with session.put(f"/locations/{name}", json={"stress_factor": factor}) as answer:
            answer.raise_for_status()
    for tail in tails:
        async with session.get(f"/aircraft/{tail}/inspections") as answer:
            found = [i for i in await answer.json() if i["crack_length_m"] is not None]
        for name, _ in PLACES[:count]:
            body = [
                {
                    "inspection_id": f"{i['inspection_id']}-{name}",
                    "inspected_at": i["inspected_at"],
                    "crack_length_m": i["crack_length_m"],
                    "location": name,
                }
                for i in found
            ]
            if body:
                async with session.post(f"/aircraft/{tail}/inspections", json=body) as answer:
                    answer.raise_for_status()
    started = time.monotonic()
    async with session.post("/models/retrain") as answer:
        jobs = (await answer.json())["jobs"]
    done = dict(zip(jobs, await wait_for_jobs(session, list(jobs.values())), strict=True))
    seconds = time.monotonic() - started
    assert {job["status"] for job in done.values()} == {"succeeded"}, done
    return seconds, {name: _outcome(job) for name, job in done.items()}


def _outcome(job: dict[str, Any]) -> dict[str, Any]:
    """A finished retrain job's status, outcome and the reason in words."""
    return {k: job.get(k) for k in ("status", "outcome", "outcome_reason", "model_version")}


def cpu_seconds(pid: int) -> float:
    """CPU seconds (user + system) the process and its descendants have used so far (Linux
    /proc): what the load cost the API processes, whatever else shares the machine."""
    ticks = os.sysconf("SC_CLK_TCK")
    total = 0.0
    pending = [pid]
    while pending:
        found = pending.pop()
        try:
            fields = Path(f"/proc/{found}/stat").read_text().rsplit(")", 1)[1].split()
            children = Path(f"/proc/{found}/task/{found}/children").read_text().split()
        except FileNotFoundError:  # ended meanwhile
            continue
        total += (int(fields[11]) + int(fields[12])) / ticks  # utime, stime
        pending += [int(child) for child in children]
    return total


async def run_load(
    base: str,
    headers: dict[str, str],
    clients: int,
    seconds: float,
    ingests_per_s: float,
    locations: int = 0,
    settle_s: float = 0.0,
    retrain: bool = True,
    api_pid: int | None = None,
) -> dict[str, Any]:
    """The load against the service at `base`; api_pid: its `fleetpinn serve` process, whose
    CPU over the load is reported per request."""
    connector = aiohttp.TCPConnector(limit=clients + 1)  # each client, and the ingests
    async with aiohttp.ClientSession(
        base,
        connector=connector,
        headers=headers,
        timeout=aiohttp.ClientTimeout(total=60),
    ) as session:

        async def get_json(path: str, **params: Any) -> Any:
            async with session.get(path, params=params) as answer:
                answer.raise_for_status()
                return await answer.json()

        listed = (await get_json("/aircraft", limit=1000))["items"]
        tails = [a["tail"] for a in listed]
        last_flown = {a["tail"]: pd.Timestamp(a["last_flown_at"]) for a in listed}
        first_retrain_s, first_retrain = (
            await add_locations(session, tails, locations) if locations else (None, None)
        )
        for tail in tails[:5]:  # warm: first requests load the model and compile nothing more
            await get_json(f"/aircraft/{tail}/forecast")
        await asyncio.sleep(settle_s)
        jobs: dict[str, str] = {}
        if retrain:
            async with session.post("/models/retrain") as answer:
                jobs = (await answer.json())["jobs"]
        recorder = Recorder()
        cpu_before = None if api_pid is None else cpu_seconds(api_pid)
        load_before = os.getloadavg()
        started = time.monotonic()
        until = started + seconds
        await asyncio.gather(
            ingest_loop(session, recorder, last_flown, ingests_per_s, until),
            *(client_loop(session, recorder, tails, n, until) for n in range(clients)),
        )
        elapsed = time.monotonic() - started
        api_cpu_s = (
            None if cpu_before is None or api_pid is None else cpu_seconds(api_pid) - cpu_before
        )
        during = {name: await _job_state(session, job_id) for name, job_id in jobs.items()}
    total = sum(len(v) for v in recorder.latency_ms.values())
    return {
        "clients": clients,
        "ingests_per_s": ingests_per_s,
        "seconds": round(elapsed, 1),
        "requests": total,
        "requests_per_s": round(total / elapsed, 1),
        "errors": sum(len(v) for v in recorder.errors.values()),
        # CPU of the API processes over the load, per request answered: the route's cost,
        # which the machine's other work does not move as it moves the latency
        "api_cpu_ms_per_request": None
        if api_cpu_s is None
        else round(1000 * api_cpu_s / max(total, 1), 2),
        "load_average_before_after": [round(v, 2) for v in (*load_before, *os.getloadavg())],
        "routes": recorder.summary(),
        "retrain_during_load": during or None,
        "locations": 1 + locations,
        "settle_s": settle_s,
        "first_retrain_of_every_location_s": None
        if first_retrain_s is None
        else round(first_retrain_s, 1),
        "first_retrain_of_every_location": first_retrain,
    }


async def _job_state(session: aiohttp.ClientSession, job_id: str) -> dict[str, Any]:
    """A job's status and progress, with its duration once finished."""
    async with session.get(f"/jobs/{job_id}") as answer:
        if not answer.ok:
            return {"status": f"unknown: {answer.status} {(await answer.text())[:200]}"}
        job = await answer.json()
    state: dict[str, Any] = {"status": job["status"], "progress": job["progress"]}
    if job.get("outcome"):
        state.update(outcome=job["outcome"], outcome_reason=job["outcome_reason"])
    if job.get("started_at") and job.get("finished_at"):
        span = pd.Timestamp(job["finished_at"]) - pd.Timestamp(job["started_at"])
        state["seconds"] = round(span.total_seconds(), 1)
    return state


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--backend", choices=("sqlite", "postgresql"), default="sqlite")
    parser.add_argument("--aircraft-per-mix", type=int, default=100)
    parser.add_argument("--years", type=int, default=5)
    parser.add_argument("--clients", type=int, default=32)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--ingests-per-s", type=float, default=1.0)
    parser.add_argument("--log", type=Path, default=None, help="keep the server's log here")
    parser.add_argument("--api-processes", type=int, default=2, help="fleetpinn serve --processes")
    parser.add_argument(
        "--locations",
        type=int,
        default=0,
        choices=range(len(PLACES) + 1),
        help="control points catalogued beside the default one (each inspected where it is)",
    )
    parser.add_argument(
        "--settle-s",
        type=float,
        default=0.0,
        help="seconds between the service's start (with --locations, the end of the first "
        "retrain of every location) and the load: a service up a while",
    )
    parser.add_argument(
        "--no-answers-ahead",
        action="store_true",
        help="API processes make no forecast before it is asked (FLEETPINN_ANSWERS_AHEAD=0)",
    )
    parser.add_argument(
        "--no-retrain",
        action="store_true",
        help="queue no retrain with the load: reads and ingests alone",
    )
    parser.add_argument(
        "--worker",
        choices=("thread", "process"),
        default="process",
        help="run the retrain in a `fleetpinn worker` process or the API's worker thread",
    )
    parser.add_argument(
        "--seeded",
        type=Path,
        default=None,
        help="start from a copy of this SQLite file (kept by --keep-seeded) instead of seeding",
    )
    parser.add_argument(
        "--keep-seeded",
        type=Path,
        default=None,
        help="copy the seeded and trained SQLite file here before the load",
    )
    args = parser.parse_args()
    if (args.seeded or args.keep_seeded) and args.backend != "sqlite":
        parser.error("--seeded and --keep-seeded take a SQLite file: --backend sqlite")
    with (
        tempfile.TemporaryDirectory(prefix="fleetpinn-load-") as folder,
        database(args.backend, Path(folder)) as url,
    ):
        setup = _setup(url, Path(folder) / "fleetpinn.db", args)
        env = {**SERVICE_ENV, "FLEETPINN_DATABASE_URL": url}
        if args.no_answers_ahead:
            env["FLEETPINN_ANSWERS_AHEAD"] = "0"
        workers = []
        if args.worker == "process":
            env["FLEETPINN_RUN_WORKER"] = "0"
            workers.append(start_worker(env, Path(folder) / "worker.log"))
        server = start_service(env, Path(folder) / "server.log", processes=args.api_processes)
        try:
            result = asyncio.run(
                run_load(
                    server.base,
                    admin_key(url),
                    args.clients,
                    args.seconds,
                    args.ingests_per_s,
                    args.locations,
                    args.settle_s,
                    retrain=not args.no_retrain,
                    api_pid=server.process.pid,
                )
            )
        finally:
            for process in (server, *workers):
                process.stop()
        if args.log:
            args.log.write_text(server.text())
        result["server_exceptions"] = _exceptions(server.text())
    layout = {
        "worker": args.worker,
        "api_processes": args.api_processes,
        "answers_ahead": not args.no_answers_ahead,
        "retrain": not args.no_retrain,
    }
    print(json.dumps({"backend": args.backend, **layout, "setup": setup, **result}))


def _setup(url: str, file: Path, args: argparse.Namespace) -> dict[str, Any]:
    """The database at `url` (the SQLite `file`) seeded and trained, or copied from --seeded;
    kept at --keep-seeded."""
    if args.seeded is not None:
        shutil.copyfile(args.seeded, file)
        return {"seeded_from": str(args.seeded)}
    setup = seed(url, aircraft_per_mix=args.aircraft_per_mix, years=args.years, train=True)
    if args.keep_seeded is not None:
        shutil.copyfile(file, args.keep_seeded)
    return setup


def _exceptions(log: str) -> dict[str, int]:
    """The server log's exception lines (the last line of each traceback), counted."""
    lines = log.splitlines()
    found: dict[str, int] = defaultdict(int)
    for before, line in itertools.pairwise(lines):
        if before.startswith("  ") and line and not line.startswith((" ", "INFO", "Traceback")):
            found[line[:200]] += 1
    return dict(found)


if __name__ == "__main__":
    main()
