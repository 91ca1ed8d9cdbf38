from concurrent.futures import ThreadPoolExecutor
from datetime import timedelta

import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.db import make_engine, make_session_factory
from app.local_server import wait_for_job
from app.services import models as model_service
from app.services.jobs.retrain import run_retrain
from tests.app.conftest import START, add_tail, inspect


def _inspected_fleet(client: TestClient, tails: int) -> None:
    for i in range(tails):
        tail = f"N{i:03d}"
        add_tail(client, tail, 40, stress=100.0 + 5 * i)
        inspect(client, tail, START + timedelta(days=11), 0.00502 + 0.00001 * i)


def test_retrain_stores_validates_and_activates_a_version(client: TestClient) -> None:
    _inspected_fleet(client, 5)
    accepted = client.post("/models/retrain", json={})
    assert accepted.status_code == 202
    job = wait_for_job(client, accepted.json()["job_id"])
    assert job["status"] == "succeeded", job["error"]
    assert job["progress"] == 1.0
    assert job["stage"] == "done"
    assert job["model_version"] == 1
    # 5 inspected tails: round(0.2 * 5) = 1 held out for validation, 4 trained on.
    assert job["metrics"]["validation"]["count"] == 1
    assert job["metrics"]["train"]["count"] == 4
    assert job["metrics"]["validation"]["mean_abs_pct_error"] >= 0
    version = client.get("/models/1").json()
    assert version["status"] == "active"
    assert len(version["training"]["validation_tails"]) == 1
    assert client.get("/ready").json()["model_version"] == 1


def test_retrain_without_activation_then_rollback(client: TestClient) -> None:
    _inspected_fleet(client, 2)
    first = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
    assert first["status"] == "succeeded"
    second = wait_for_job(
        client, client.post("/models/retrain", json={"activate": False}).json()["job_id"]
    )
    assert second["model_version"] == 2
    statuses = {m["version"]: m["status"] for m in client.get("/models").json()}
    assert statuses == {1: "active", 2: "candidate"}
    # Forecasts keep coming from the active version.
    assert client.get("/aircraft/N000/forecast").json()["model_version"] == 1
    assert client.post("/models/2/activate").json()["status"] == "active"
    assert client.get("/aircraft/N000/forecast").json()["model_version"] == 2
    rolled_back = client.post("/models/1/activate").json()
    assert rolled_back["status"] == "active"
    statuses = {m["version"]: m["status"] for m in client.get("/models").json()}
    assert statuses == {1: "active", 2: "retired"}
    assert client.post("/models/9/activate").status_code == 404


def test_retrain_without_inspections_fails_with_a_reason(client: TestClient) -> None:
    add_tail(client, "N001", 10)
    job = wait_for_job(client, client.post("/models/retrain").json()["job_id"])
    assert job["status"] == "failed"
    assert "crack measurement" in job["error"]
    assert client.get("/models").json() == []


def test_hybrid_retrain_with_a_small_budget(client: TestClient) -> None:
    _inspected_fleet(client, 3)
    body = {"kernel": "residual", "lbfgs_iterations": 3, "hidden": [[3, "tanh"]]}
    job = wait_for_job(client, client.post("/models/retrain", json=body).json()["job_id"])
    assert job["status"] == "succeeded", job["error"]
    spec = client.get(f"/models/{job['model_version']}").json()["spec"]
    assert spec["kernel"] == "residual"
    assert spec["hidden"] == [[3, "tanh"]]


def test_unknown_job_and_bad_retrain_body(client: TestClient) -> None:
    assert client.get("/jobs/nope").status_code == 404
    assert client.post("/models/retrain", json={"kernel": "lstm"}).status_code == 422
    assert client.post("/models/retrain", json={"surprise": 1}).status_code == 422


def test_each_thread_marches_its_own_copy_of_a_version(client: TestClient) -> None:
    """Posterior draws swap a module's parameters while they march (functional_call), so two
    threads must never share one model object: each gets its own, and keeps it."""
    _inspected_fleet(client, 1)
    assert wait_for_job(client, client.post("/models/retrain").json()["job_id"])["status"] == (
        "succeeded"
    )
    factory = client.app.state.session_factory  # type: ignore[attr-defined]

    def load() -> object:
        with factory() as session:
            return model_service.load_posterior(session, 1)

    mine = load()
    with ThreadPoolExecutor(max_workers=1) as pool:
        theirs, theirs_again = pool.submit(load).result(), pool.submit(load).result()
    assert load() is mine and theirs is theirs_again and theirs is not mine


def test_a_rerun_finishes_the_version_its_dead_attempt_stored(
    client: TestClient, settings: Settings
) -> None:
    """A job run again after its worker died (app.services.jobs.queue) makes no second version, and
    acts on the stored one as its params ask (a candidate here, as asked;
    tests/app/test_retrain_activation.py: one that passed its gate is activated)."""
    _inspected_fleet(client, 2)
    params = {"activate": False}
    job_id = client.post("/models/retrain", json=params).json()["job_id"]
    assert wait_for_job(client, job_id)["model_version"] == 1
    with make_session_factory(make_engine(settings.database_url))() as session:
        result = run_retrain(
            session, job_id=job_id, params=params, settings=settings, progress=lambda *_: None
        )
    assert (result["model_version"], result["outcome"]) == (1, "candidate")
    assert "earlier attempt of this job" in result["reason"]
    assert [v["status"] for v in client.get("/models").json()] == ["candidate"]


def test_retrain_choices_come_from_the_model_registries() -> None:
    """RetrainIn's kernel, activation and optimizer are the registries' names (model.cells
    KERNELS, model.nets ACTIVATIONS, model.train OPTIMIZERS), in validation and in the schema,
    a kernel registered later included."""
    from pydantic import ValidationError

    from app.schemas import RetrainIn
    from model.cells import KERNELS, PhysicsKernel
    from model.nets import ACTIVATIONS
    from model.train import OPTIMIZERS

    schema = RetrainIn.model_json_schema()["properties"]
    assert schema["kernel"]["anyOf"][0]["enum"] == list(KERNELS)
    assert schema["optimizer"]["anyOf"][0]["enum"] == list(OPTIMIZERS)
    hidden = schema["hidden"]["anyOf"][0]["items"]["prefixItems"][1]
    assert hidden["enum"] == list(ACTIVATIONS)
    with pytest.raises(ValidationError, match="kernel must be one of"):
        RetrainIn(kernel="lstm")
    KERNELS["physics-again"] = PhysicsKernel
    try:
        assert RetrainIn(kernel="physics-again").kernel == "physics-again"
        assert (
            "physics-again"
            in RetrainIn.model_json_schema()["properties"]["kernel"]["anyOf"][0]["enum"]
        )
    finally:
        del KERNELS["physics-again"]
