"""What the service subcommands of `fleetpinn` do (app.cli.service only parses their arguments).

serve, migrate, worker, retrain, forecast-batch and seed-demo all act on the database named by
FLEETPINN_DATABASE_URL (app.config.Settings).
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from app import logs
from app import migrate as migrations
from app.config import KEEP_ALIVE_SECONDS, Settings, get_settings
from app.db import make_engine, make_session_factory

# `fleetpinn keys` itself uses app.key_admin, which starts without the model stack
from app.key_admin import create_key as create_key
from app.key_admin import list_keys as list_keys
from app.key_admin import revoke_key as revoke_key
from app.reuse_port import serve_processes
from app.services import audit
from app.services.jobs import queue as jobs
from app.services.ranking import export
from app.services.records import ingest
from app.worker import Worker, run_pending
from model.runtime import configure_threads, warm_up


def serve(
    host: str = "127.0.0.1",
    port: int = 8000,
    settings: Settings | None = None,
    *,
    processes: int = 1,
) -> None:
    """Apply migrations, then serve the API with uvicorn (docs at /docs) from `processes`
    processes on one port (more than one: each its own GIL and its own socket,
    app.reuse_port; on SQLite or PostgreSQL alike)."""
    import uvicorn

    settings = settings or get_settings()
    logs.configure(settings.log_format, settings.log_level)
    migrations.upgrade(settings.database_url)  # once, before the processes start
    if processes > 1:
        raise SystemExit(serve_processes(host, port, processes))
    # Our handler formats uvicorn's lines too; app.middleware writes the request lines.
    uvicorn.run(
        "app.main:app",
        host=host,
        port=port,
        log_config=None,
        access_log=False,
        timeout_keep_alive=KEEP_ALIVE_SECONDS,
    )


def migrate(settings: Settings | None = None) -> None:
    """Bring the database schema to the newest revision."""
    migrations.upgrade((settings or get_settings()).database_url)


def worker(
    *,
    once: bool = False,
    metrics_port: int | None = None,
    metrics_host: str = "127.0.0.1",
    settings: Settings | None = None,
) -> int:
    """Run queued jobs: until none is left (once) or forever.  Returns the jobs run (once).
    metrics_port: serve this process's Prometheus metrics (app.metrics) on that port of
    metrics_host (loopback unless told otherwise: prometheus_client's default is every
    interface)."""
    settings = settings or get_settings()
    configure_threads()
    logs.configure(settings.log_format, settings.log_level)
    if metrics_port is not None:
        from prometheus_client import start_http_server

        start_http_server(metrics_port, addr=metrics_host)
    migrations.upgrade(settings.database_url)
    factory = make_session_factory(make_engine(settings.database_url))
    # its jobs run below the API's requests on the same cores, its cache thread halfway
    runner = Worker(factory, settings, name="cli", nice=settings.worker_nice)
    if once:
        return run_pending(factory, settings, runner.name)
    warm_up()  # a long-lived worker compiles (or loads) the march once, up front
    runner.run_forever()
    return 0


# Progress of a job as its record shows it: (fraction done, stage in words or None).
OnProgress = Callable[[float, str | None], None]
_WATCH_EVERY_S = 0.25


def _run_now(
    kind: str, params: dict[str, Any], settings: Settings, on_progress: OnProgress | None = None
) -> dict[str, Any]:
    """Queue a job and run it in this process (a thread; this one reads its record and tells
    on_progress); returns the job's final record."""
    configure_threads()
    migrations.upgrade(settings.database_url)
    factory = make_session_factory(make_engine(settings.database_url))
    with factory() as session:
        job_id = jobs.enqueue(session, kind, params, actor=audit.local(kind)).id
    # Runs this job and any queued before it; another worker may hold it, so wait for its end.
    runner = threading.Thread(
        target=run_pending, args=(factory, settings, f"cli:{kind}"), name="fleetpinn-cli-job"
    )
    runner.start()
    try:
        while True:
            with factory() as session:
                job = jobs.get_job(session, job_id)
                if on_progress is not None:
                    on_progress(job.progress, job.stage)
                if job.status in jobs.FINISHED:
                    return {
                        "job_id": job.id,
                        "status": job.status,
                        "result": job.result,
                        "error": job.error,
                    }
            time.sleep(_WATCH_EVERY_S if runner.is_alive() else settings.worker_poll_seconds)
    finally:
        runner.join()


def retrain(
    params: dict[str, Any],
    settings: Settings | None = None,
    on_progress: OnProgress | None = None,
) -> dict[str, Any]:
    """Train a new model version now (see POST /models/retrain for params)."""
    return _run_now("retrain", params, settings or get_settings(), on_progress)


def forecast_batch(
    out: Path | None = None,
    settings: Settings | None = None,
    on_progress: OnProgress | None = None,
    *,
    refresh: bool = False,
) -> dict[str, Any]:
    """Forecast the whole fleet under the active model (app.services.jobs.batch: the tails without a
    current forecast, or every tail with `refresh`), store it, and export it to `out`."""
    settings = settings or get_settings()
    params = {"refresh": True} if refresh else {}
    outcome = _run_now("forecast-batch", params, settings, on_progress)
    if outcome["status"] != "succeeded" or out is None:
        return outcome
    factory = make_session_factory(make_engine(settings.database_url))
    with factory() as session:
        # several locations: every (tail, location) row, as GET /forecasts and client export
        several = "locations" in outcome["result"]
        version = None if several else int(outcome["result"]["model_version"])
        frame = export.export_frame(session, settings, version=version)
    out.write_bytes(export.encode(frame, export.format_of(out.suffix)))
    return {**outcome, "out": str(out), "rows": len(frame)}


def seed_demo(
    *,
    inspected: int = 15,
    selection: str = "uniform-coverage",
    aircraft_per_mix: int = 100,
    years: int = 5,
    seed: int = 0,
    discrepancy: float = 0.0,
    growth_scatter: float = 0.0,
    sizing_error: float = 0.0,
    settings: Settings | None = None,
    on_progress: OnProgress | None = None,
) -> dict[str, Any]:
    """Store the synthetic thesis fleet (3 x aircraft_per_mix tails) with `inspected` inspections.

    discrepancy: the truth's geometry-factor growth that the physics lacks (model.fleet), so the
    hybrid model has something to learn.  growth_scatter: sd of ln growth rate across tails;
    sizing_error: sd of ln(measured / true) of the inspections (the real world's).  Re-running is harmless: the same rows count as
    duplicates.
    """
    from model.fleet import FleetConfig, generate_fleet, scheduled_inspection

    settings = settings or get_settings()

    def stage(done: float, words: str) -> None:
        if on_progress is not None:
            on_progress(done, words)

    stage(0.0, "migrating")
    migrations.upgrade(settings.database_url)
    stage(0.05, "simulating the fleet")
    fleet = generate_fleet(
        FleetConfig(
            aircraft_per_mix=aircraft_per_mix,
            years=years,
            seed=seed,
            discrepancy=discrepancy,
            growth_scatter=growth_scatter,
        )
    )
    factory = make_session_factory(make_engine(settings.database_url))
    flights = fleet.flights_frame()
    inspections = fleet.inspections_frame(
        scheduled_inspection(fleet, inspected, selection, noise_sd=sizing_error, seed=seed)
    )
    actor = audit.local("seed-demo")
    with factory() as session:
        stage(0.3, f"storing {len(flights):,} flights")
        stored = ingest.ingest_flights(
            session, flights, source="fleet", create_tails=True, actor=actor, settings=settings
        )
        stage(0.95, "storing inspections")
        checked = ingest.ingest_inspections(
            session, inspections, source="inspections", actor=actor, settings=settings
        )
    stage(1.0, "done")
    return {
        "aircraft": fleet.size,
        "flights": {"inserted": stored.inserted, "duplicates": stored.duplicates},
        "aircraft_created": stored.aircraft_created,
        "inspections": {"inserted": checked.inserted, "duplicates": checked.duplicates},
    }


def dumps(value: Any) -> str:
    return json.dumps(value, indent=2, default=str)
