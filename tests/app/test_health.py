from fastapi.testclient import TestClient


def test_health_and_ready_without_a_model(client: TestClient) -> None:
    assert client.get("/health").json() == {"status": "ok"}
    ready = client.get("/ready")
    assert ready.status_code == 200
    assert ready.json() == {
        "status": "ready",
        "database": True,
        "model_version": None,
        "model_versions": {},
    }


def test_openapi_docs_are_served(client: TestClient) -> None:
    assert client.get("/docs").status_code == 200
    paths = client.get("/openapi.json").json()["paths"]
    for path in (
        "/aircraft/{tail}",
        "/flights/upload",
        "/models/retrain",
        "/jobs/{job_id}",
        "/aircraft/{tail}/forecast",
        "/fleet/ranking",
        "/forecasts/batch",
    ):
        assert path in paths
