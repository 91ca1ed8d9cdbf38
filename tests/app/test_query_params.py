"""A one-value query parameter sent more than once is a 422 naming it, on every route (issue 42:
`GET /audit?action=a&action=b` took the last value and answered 200); app.query_params."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any

import pytest
from fastapi import Depends, FastAPI, Query
from fastapi.testclient import TestClient
from httpx import Response

from app.query_params import one_value_each
from tests.app.conftest import add_tail, bearer, new_key, serving, settings_in

PEARL = {"description": "Wing root", "stress_factor": 1.2}


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """A SQLite file with tail Q1 (8 flights) and the catalogue entry `pearl`."""
    with serving(settings_in(Path(tmp_path_factory.mktemp("query")))) as test_client:
        add_tail(test_client, "Q1", 8)
        assert test_client.put("/locations/pearl", json=PEARL).status_code == 201
        yield test_client


def _refused(answer: Response, name: str, times: int) -> dict[str, Any]:
    body: dict[str, Any] = answer.json()
    assert answer.status_code == 422, body
    first = body["detail"][0]
    assert first["loc"] == ["query", name]
    assert first["msg"] == f"{name}: given {times} times; it takes one value"
    assert "Traceback" not in answer.text
    return body


@pytest.mark.parametrize(
    ("url", "name", "times"),
    [
        ("/audit?action=a&action=b", "action", 2),
        ("/aircraft?limit=5&offset=0&limit=6&limit=7", "limit", 3),
        # declared by a dependency of the route (app.deps.horizon_days, bounded_as_of)
        ("/aircraft/Q1/forecast?horizon_days=30&horizon_days=60", "horizon_days", 2),
        ("/aircraft/Q1/forecast?as_of=2024-01-01&as_of=2024-01-02", "as_of", 2),
        # an open route, its parameter under an alias
        ("/pages/login?next=/pages/fleet&next=/pages/models", "next", 2),
    ],
)
def test_a_one_value_parameter_given_twice_is_refused_naming_it(
    client: TestClient, url: str, name: str, times: int
) -> None:
    assert _refused(client.get(url), name, times)["reason"].startswith(f"{name}: given")


def test_each_repeated_parameter_is_named_and_single_ones_still_answer(client: TestClient) -> None:
    answer = client.get("/audit?limit=2&subject=Q1&limit=3&subject=Q2")
    assert answer.status_code == 422
    assert [e["loc"] for e in answer.json()["detail"]] == [["query", "limit"], ["query", "subject"]]
    assert client.get("/audit?limit=2&subject=Q1").json()["limit"] == 2
    # a parameter the route does not declare is ignored, repeated or not
    assert client.get("/aircraft?limit=1&colour=a&colour=b").json()["limit"] == 1


def test_a_write_with_a_repeated_parameter_changes_nothing(client: TestClient) -> None:
    answer = client.delete("/locations/pearl?force=false&force=true")
    _refused(answer, "force", 2)
    assert client.get("/locations/pearl").status_code == 200
    events = client.get("/audit?subject=pearl").json()["items"]
    assert [e["action"] for e in events] == ["location.create"]


def test_the_key_is_checked_before_a_repeated_parameter(client: TestClient) -> None:
    """A repeated parameter was checked app-wide, before the key: no key answered 422."""
    wrong = "fpk_00000000_" + "A" * 43
    for headers in ({"Authorization": ""}, bearer(wrong)):
        answer = client.get("/audit?action=a&action=b", headers=headers)
        assert answer.status_code == 401, answer.text
    reader = new_key(client.app, "read")  # type: ignore[arg-type]
    answer = client.delete("/locations/pearl?force=false&force=true", headers=bearer(reader))
    assert answer.status_code == 403, answer.text
    _refused(client.get("/aircraft?limit=5&limit=6", headers=bearer(reader)), "limit", 2)
    assert client.get("/locations/pearl").status_code == 200


def test_a_list_valued_parameter_stays_repeatable() -> None:
    """No route of the app declares one today; a route that does gathers every value."""
    app = FastAPI(dependencies=[Depends(one_value_each)])

    @app.get("/tags")
    def tags(
        tag: Annotated[list[str] | None, Query()] = None, limit: int = 10
    ) -> dict[str, object]:
        return {"tag": tag, "limit": limit}

    with TestClient(app) as test_client:
        assert test_client.get("/tags?tag=a&tag=b").json() == {"tag": ["a", "b"], "limit": 10}
        _refused(test_client.get("/tags?tag=a&limit=1&limit=2"), "limit", 2)
