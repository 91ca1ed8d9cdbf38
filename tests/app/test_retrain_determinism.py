"""A retrain of the same stored data makes the same models whatever order its jobs (one per
location) are claimed in, in one process or two, whatever job ran before in the process,
whatever the global random state and whatever another thread draws from it meanwhile (issue
20: a model's initial weights drawn from a generator of its own, seeded; sorted reads)."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import torch
from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from app.config import Settings
from app.services import audit
from app.services.jobs import retrain
from app.tables import Job, Location, ModelVersion
from app.worker import run_job
from model import artifacts
from tests.app.conftest import stored_two_location_fleet

ACTOR = audit.local("test")
ROOT = Path(__file__).resolve().parents[2]
# `fleetpinn worker --once` from this checkout (the console script may name another)
_WORKER = "import sys; from app.cli import main; sys.exit(main(sys.argv[1:]))"
WING = {"stress_factor": 1.05, "initial_crack_m": 0.004, "critical_crack_m": 0.045}


def _stored_fleet(settings: Settings) -> sessionmaker[Session]:
    """conftest's six tails, at the default location and a wing location whose cracks measure
    0.9 of the default's."""
    return stored_two_location_fleet(settings, "wing", WING, crack_scale=0.9)


@contextmanager
def _drawing_meanwhile() -> Iterator[None]:
    """Another thread of the process drawing from torch's global generator all along, as the
    worker's cache thread and the API's requests do when they load a model (nn.Linear draws its
    initial weights from it)."""
    stop = threading.Event()

    def draw() -> None:
        while not stop.wait(0.0005):
            torch.rand(1)

    thread = threading.Thread(target=draw, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


def _retrain_here(factory: sessionmaker[Session], settings: Settings) -> None:
    """Queue a retrain (one job per location) and run its jobs in this process in the reverse
    of the order they were queued (a worker claims the oldest first), the global generators
    disturbed before each and drawn from by another thread meanwhile."""
    with factory() as session:
        _, queued = retrain.enqueue_retrains(session, {}, actor=ACTOR)
    with _drawing_meanwhile():
        for job_id in reversed(list(queued.values())):
            torch.rand(17)
            np.random.rand(5)
            assert run_job(factory, job_id, settings) == "succeeded"


def _retrain_in_two_workers(factory: sessionmaker[Session], env: dict[str, str]) -> None:
    """Queue a retrain and run it in two `fleetpinn worker --once` processes, which claim its
    jobs in whatever order their start lets them."""
    with factory() as session:
        _, queued = retrain.enqueue_retrains(session, {}, actor=ACTOR)
    workers = [
        subprocess.Popen([sys.executable, "-c", _WORKER, "worker", "--once"], env=env)
        for _ in range(2)
    ]
    assert [worker.wait(timeout=600) for worker in workers] == [0, 0]
    with factory() as session:
        finished = session.scalars(select(Job.status).where(Job.id.in_(queued.values())))
        assert set(finished) == {"succeeded"}


def _digest(value: Any) -> str:
    """SHA-256 of a model file's entry: tensors by their bytes, dicts key by key, the rest by
    repr."""
    digest = hashlib.sha256()

    def add(item: Any) -> None:
        if isinstance(item, dict):
            for key in sorted(item):
                digest.update(str(key).encode())
                add(item[key])
        elif isinstance(item, torch.Tensor):
            digest.update(item.detach().contiguous().numpy().tobytes())
        else:
            digest.update(repr(item).encode())

    add(value)
    return digest.hexdigest()


def _fingerprints(factory: sessionmaker[Session]) -> dict[str, list[dict[str, Any]]]:
    """Per location, in version order: each version's parameters and weights' posterior
    (hashed), spec, fitted tracking (growth spread, path drift, sizing) and validation errors."""
    out: dict[str, list[dict[str, Any]]] = {}
    with factory() as session:
        rows = session.execute(
            select(Location.name, ModelVersion.spec, ModelVersion.weights, ModelVersion.metrics)
            .join(ModelVersion, ModelVersion.location_id == Location.id)
            .order_by(ModelVersion.version)
        ).all()
    for name, spec, weights, metrics in rows:
        model, _ = artifacts.from_bytes(weights)
        out.setdefault(name, []).append(
            {
                "parameters": _digest(model.state_dict()),
                "posterior": _digest(artifacts.posterior_from_bytes(weights)),
                "spec": spec,
                "tracking": metrics["tracking"],
                "validation": metrics["validation"],
            }
        )
    return out


def test_a_retrain_in_another_order_and_processes_makes_the_same_models(tmp_path: Path) -> None:
    overrides = {
        "DATABASE_URL": f"sqlite:///{tmp_path / 'fleet.db'}",
        "AS_OF": "2022-01-01",
        "LBFGS_ITERATIONS": "15",
        "POSTERIOR_RESTARTS": "2",
        "KERNEL": "residual",  # a network's weights: the fit whose order could matter
    }
    env = {
        **os.environ,
        **{f"FLEETPINN_{name}": value for name, value in overrides.items()},
        "PYTHONPATH": os.pathsep.join((str(ROOT), os.environ.get("PYTHONPATH", ""))),
        "OMP_NUM_THREADS": "1",
    }
    settings = Settings(**{name.lower(): value for name, value in overrides.items()})
    factory = _stored_fleet(settings)
    _retrain_here(factory, settings)
    _retrain_in_two_workers(factory, env)
    versions = _fingerprints(factory)
    assert set(versions) == {"default", "wing"}
    for name, (here, in_workers) in versions.items():
        assert here == in_workers, name
    assert versions["default"][0]["parameters"] != versions["wing"][0]["parameters"]
