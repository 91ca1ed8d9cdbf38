"""A served demo fleet for the service benchmarks (load.py, scale.py): a fresh SQLite file or
PostgreSQL database (`make postgres`) holding the synthetic thesis fleet and, optionally, a
trained default model, plus the environment that makes a server or worker use them."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import date
from pathlib import Path
from typing import Any

from app import commands
from app.config import Settings
from model.fleet import DISCREPANCY_20PCT
from model.uncertainty_fit import DEFAULT_RESTARTS

# The service's own defaults (tests.app.servers starts small, fast models), as of the day after
# the demo fleet's last flight (records current, as an airline's are).
SERVICE_ENV = {
    "FLEETPINN_AS_OF": "2025-01-01",
    "FLEETPINN_KERNEL": "residual",
    "FLEETPINN_POSTERIOR_RESTARTS": str(DEFAULT_RESTARTS),
    "FLEETPINN_WORKER_POLL_SECONDS": "0.5",
}


@contextmanager
def database(backend: str, folder: Path) -> Iterator[str]:
    """The URL of a new empty database, dropped (PostgreSQL) when done."""
    if backend == "sqlite":
        yield f"sqlite:///{folder / 'fleetpinn.db'}"
        return
    from tests import postgres

    if reason := postgres.unavailable():
        raise SystemExit(reason)
    name = postgres.create_database("fleetpinn_bench")
    try:
        yield postgres.url_of(name)
    finally:
        postgres.drop_database(name)


def admin_key(url: str) -> dict[str, str]:
    """Headers with a new admin API key of the database at `url`."""
    key = commands.create_key(
        "admin", "benchmark", replace=True, settings=Settings(database_url=url)
    )
    return {"Authorization": f"Bearer {key.key}"}


def service_settings(url: str) -> Settings:
    """The settings the benchmark's servers run with (SERVICE_ENV), for work done in this
    process: a first version trained here caches its risk for the servers' as-of date."""
    return Settings(
        database_url=url,
        as_of=date.fromisoformat(SERVICE_ENV["FLEETPINN_AS_OF"]),
        kernel=SERVICE_ENV["FLEETPINN_KERNEL"],
        posterior_restarts=int(SERVICE_ENV["FLEETPINN_POSTERIOR_RESTARTS"]),
    )


def seed(url: str, *, aircraft_per_mix: int, years: int, train: bool) -> dict[str, Any]:
    """Store the demo fleet (15 inspected, the 20 % discrepancy of `make demo`) and train the
    default model on it in this process, as the servers will run; returns what it did and how
    long it took."""
    settings = service_settings(url)
    started = time.perf_counter()
    stored = commands.seed_demo(
        aircraft_per_mix=aircraft_per_mix,
        years=years,
        discrepancy=DISCREPANCY_20PCT,
        settings=settings,
    )
    summary: dict[str, Any] = {"seed_s": round(time.perf_counter() - started, 1), **stored}
    if train:
        started = time.perf_counter()
        outcome = commands.retrain({}, settings)
        assert outcome["status"] == "succeeded", outcome
        summary["first_retrain_s"] = round(time.perf_counter() - started, 1)
    return summary
