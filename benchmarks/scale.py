"""Two API processes and two `fleetpinn worker` processes on one PostgreSQL database.

    make postgres
    .venv/bin/python -m benchmarks.scale                 # 300 x 7,300 flights, 3 + 3 jobs
    .venv/bin/python -m benchmarks.scale --aircraft-per-mix 10 --years 1 --jobs 4   # quicker

Stores the demo fleet and trains the default model (benchmarks.fleetdb), then starts two
`python -m uvicorn app.main:app` processes without their in-process worker and two
`fleetpinn worker` processes, all with the service's defaults.  Queues --jobs retrains through
one API and --jobs fleet forecast batches through the other, and while the workers run them
asks both APIs for single-aircraft forecasts (one client, back to back).  Checks from the jobs
table: every job succeeded after exactly one attempt, each retrain stored exactly one version,
and which worker ran what.  Prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import random
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
from sqlalchemy import func, select

from app.db import make_engine
from app.local_server import ServiceProcess, start_uvicorn, start_worker
from app.tables import Job, ModelVersion
from benchmarks.fleetdb import SERVICE_ENV, admin_key, database, seed


class Prober(threading.Thread):
    """Forecasts from both APIs, back to back, until stopped: latency and failures."""

    def __init__(self, bases: list[str], tails: list[str], headers: dict[str, str]) -> None:
        super().__init__(daemon=True)
        self.bases, self.tails, self.headers = bases, tails, headers
        self.latency_ms: list[float] = []
        self.failures: list[str] = []
        self.stop = threading.Event()

    def run(self) -> None:
        pick = random.Random(0)
        clients = [httpx.Client(base_url=b, timeout=60, headers=self.headers) for b in self.bases]
        while not self.stop.is_set():
            client = pick.choice(clients)
            started = time.perf_counter()
            try:
                answer = client.get(f"/aircraft/{pick.choice(self.tails)}/forecast")
                if not answer.is_success:
                    self.failures.append(f"{answer.status_code}: {answer.text[:200]}")
            except httpx.HTTPError as exc:
                self.failures.append(f"{type(exc).__name__}: {exc}")
            self.latency_ms.append(1000 * (time.perf_counter() - started))
        for client in clients:
            client.close()


def _jobs_report(url: str, job_ids: list[str]) -> dict[str, Any]:
    engine = make_engine(url)
    try:
        with engine.connect() as connection:
            rows = connection.execute(
                select(
                    Job.id,
                    Job.kind,
                    Job.status,
                    Job.attempts,
                    Job.worker,
                    Job.started_at,
                    Job.finished_at,
                ).where(Job.id.in_(job_ids))
            ).all()
            versions = dict(
                connection.execute(
                    select(ModelVersion.job_id, func.count())
                    .where(ModelVersion.job_id.in_(job_ids))
                    .group_by(ModelVersion.job_id)
                ).all()
            )
    finally:
        engine.dispose()
    jobs = [
        {
            "kind": r.kind,
            "status": r.status,
            "attempts": r.attempts,
            "worker_pid": (r.worker or "::").split(":")[1],  # host:pid:name
            "seconds": round((r.finished_at - r.started_at).total_seconds(), 1),
            "versions": versions.get(r.id, 0),
        }
        for r in rows
    ]
    exactly_once = len(rows) == len(job_ids) and all(
        j["status"] == "succeeded"
        and j["attempts"] == 1
        and j["versions"] == (1 if j["kind"] == "retrain" else 0)
        for j in jobs
    )
    return {"exactly_once": exactly_once, "jobs": jobs}


def _wait_finished(
    base: str, job_ids: list[str], timeout_s: float, headers: dict[str, str]
) -> None:
    deadline = time.monotonic() + timeout_s
    with httpx.Client(base_url=base, timeout=60, headers=headers) as client:
        while time.monotonic() < deadline:
            states = [client.get(f"/jobs/{j}").json()["status"] for j in job_ids]
            if all(s in ("succeeded", "failed", "cancelled") for s in states):
                return
            time.sleep(1.0)
    raise SystemExit(f"jobs not finished after {timeout_s} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--aircraft-per-mix", type=int, default=100)
    parser.add_argument("--years", type=int, default=5)
    parser.add_argument("--jobs", type=int, default=3, help="retrains, and as many batches")
    parser.add_argument("--timeout", type=float, default=3600.0)
    args = parser.parse_args()
    with (
        tempfile.TemporaryDirectory(prefix="fleetpinn-scale-") as folder,
        database("postgresql", Path(folder)) as url,
    ):
        setup = seed(url, aircraft_per_mix=args.aircraft_per_mix, years=args.years, train=True)
        env = {**SERVICE_ENV, "FLEETPINN_DATABASE_URL": url}
        apis = [
            start_uvicorn(
                "app.main:app", {**env, "FLEETPINN_RUN_WORKER": "0"}, Path(folder) / f"api{n}.log"
            )
            for n in range(2)
        ]
        workers: list[ServiceProcess] = []
        try:
            headers = admin_key(url)
            with httpx.Client(base_url=apis[0].base, timeout=60, headers=headers) as client:
                tails = [a["tail"] for a in client.get("/aircraft?limit=1000").json()["items"]]
            prober = Prober([api.base for api in apis], tails, headers)
            prober.start()
            job_ids = []
            for k in range(args.jobs):
                with (
                    httpx.Client(base_url=apis[0].base, timeout=60, headers=headers) as first,
                    httpx.Client(base_url=apis[1].base, timeout=60, headers=headers) as second,
                ):
                    job_ids.append(first.post("/models/retrain", json={"seed": k}).json()["job_id"])
                    job_ids.append(second.post("/forecasts/batch").json()["job_id"])
            started = time.monotonic()
            workers = [start_worker(env, Path(folder) / f"worker{n}.log") for n in range(2)]
            _wait_finished(apis[0].base, job_ids, args.timeout, headers)
            wall_s = time.monotonic() - started
            prober.stop.set()
            prober.join()
        finally:
            for process in [*workers, *apis]:
                process.stop()
        report = _jobs_report(url, job_ids)
    ms = np.array(prober.latency_ms)
    print(
        json.dumps(
            {
                "setup": setup,
                "api_processes": 2,
                "worker_processes": 2,
                "jobs_wall_s": round(wall_s, 1),
                **report,
                "workers_used": len({j["worker_pid"] for j in report["jobs"]}),
                "forecasts_during_jobs": {
                    "requests": len(ms),
                    "errors": len(prober.failures),
                    "p50_ms": round(float(np.percentile(ms, 50)), 1),
                    "p99_ms": round(float(np.percentile(ms, 99)), 1),
                    "max_ms": round(float(ms.max()), 1),
                    "first_errors": sorted(set(prober.failures))[:3],
                },
            }
        )
    )


if __name__ == "__main__":
    main()
