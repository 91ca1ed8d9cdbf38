"""warm_up() compiles every loop a retrain runs (model.compile_ahead): a retrain after it, at a
default location and at one with a geometry table, adds no signature to any compiled loop, so a
worker or an image warmed up leaves no compile inside a job."""

from __future__ import annotations

import sys
from pathlib import Path

from numba.core.registry import CPUDispatcher

import model
from app.config import Settings
from app.services import audit
from app.services.jobs import retrain
from app.worker import run_job
from model.runtime import warm_up
from tests.app.conftest import stored_two_location_fleet

ACTOR = audit.local("test")
EDGE = {
    "stress_factor": 1.05,
    "initial_crack_m": 0.004,
    "critical_crack_m": 0.045,
    "geometry_table": {"crack_length_m": [0.004, 0.045], "factor": [1.12, 1.4]},
}


def _signatures() -> set[tuple[str, str]]:
    """(module.function, signature) of every compiled loop of model/ loaded so far."""
    found = set()
    for name, module in list(sys.modules.items()):
        if module is None or not name.startswith(f"{model.__name__}."):
            continue
        for attribute, value in vars(module).items():
            if isinstance(value, CPUDispatcher) and value.__module__ == name:
                found.update((f"{name}.{attribute}", str(sig)) for sig in value.signatures)
    return found


def test_a_retrain_after_warm_up_compiles_nothing(tmp_path: Path) -> None:
    settings = Settings(
        database_url=f"sqlite:///{tmp_path / 'fleet.db'}",
        as_of="2022-01-01",
        lbfgs_iterations=5,
        posterior_restarts=1,
    )
    factory = stored_two_location_fleet(settings, "edge", EDGE)
    with factory() as session:
        _, queued = retrain.enqueue_retrains(session, {}, actor=ACTOR)

    warm_up()
    warmed = _signatures()
    for job_id in queued.values():
        assert run_job(factory, job_id, settings) == "succeeded"
    assert _signatures() - warmed == set()
    compiled = {name for name, _ in warmed}
    assert {
        "model.fast_march_loops.march_record",
        "model.extrapolation._map_shaped",
        "model.shape_marginal._negative_log_marginal",
    } <= compiled
