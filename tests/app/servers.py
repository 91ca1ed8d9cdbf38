"""Service processes of the tests on the database a test names (app.local_server starts them):
small, fast models unless a test asks otherwise."""

from __future__ import annotations

from pathlib import Path

import httpx

from app import commands
from app.config import Settings
from app.local_server import ServiceProcess, start_uvicorn, start_worker
from tests.app.conftest import AS_OF, bearer

# Small fleets and a physics model keep jobs short, horizons count from the tests' "today"; a
# test overrides what it needs.
BASE_ENV = {
    "FLEETPINN_AS_OF": AS_OF.isoformat(),
    "FLEETPINN_KERNEL": "physics",
    "FLEETPINN_WORKER_POLL_SECONDS": "0.05",
    "FLEETPINN_POSTERIOR_RESTARTS": "2",
    "OMP_NUM_THREADS": "1",
}

_started = 0
_admin_keys: dict[int, str] = {}  # by id() of the server process


def _log(folder: Path, name: str) -> Path:
    global _started
    _started += 1
    return folder / f"{name}-{_started}.log"


def server(
    database_url: str, folder: Path, *, address_space_bytes: int | None = None, **env: str
) -> ServiceProcess:
    """`uvicorn app.main:app` on database_url, up (GET /health answers) when returned;
    address_space_bytes: its memory limit (app.local_server.ServiceProcess)."""
    environment = {**BASE_ENV, "FLEETPINN_DATABASE_URL": database_url, **env}
    process = start_uvicorn(
        "app.main:app",
        environment,
        _log(folder, "server"),
        address_space_bytes=address_space_bytes,
    )
    settings = Settings(database_url=database_url)
    key = commands.create_key("admin", "tests", replace=True, settings=settings).key
    _admin_keys[id(process)] = key
    return process


def admin_headers(process: ServiceProcess) -> dict[str, str]:
    """The Authorization header of the admin key made when `process` started."""
    return bearer(_admin_keys[id(process)])


def worker(database_url: str, folder: Path, **env: str) -> ServiceProcess:
    """A `fleetpinn worker` process on database_url."""
    environment = {**BASE_ENV, "FLEETPINN_DATABASE_URL": database_url, **env}
    return start_worker(environment, _log(folder, "worker"))


def client(process: ServiceProcess, timeout_s: float = 60.0) -> httpx.Client:
    """A client of the server that sends its admin key."""
    return httpx.Client(base_url=process.base, timeout=timeout_s, headers=admin_headers(process))
