"""Hostile input: schemathesis generates requests for every operation of the OpenAPI schema and
sends them to a real server (on each backend) holding a small fleet with an active model, with
an admin key and with a read key, the server limited to 4 GiB of address space (RLIMIT_AS).

No answer may be a server error, and every answer must be documented, match its schema and come
within the request time limit (30 s: requests here take well under a second, so the test runs
beside the others).  `make test` sends a few examples per operation; `python -m
benchmarks.fuzz` sends 100 or more (FLEETPINN_FUZZ_EXAMPLES) and the coverage phase
(FLEETPINN_FUZZ_PHASES), with `--checks all` every check schemathesis has
(FLEETPINN_FUZZ_CHECKS), and reports the server's peak resident memory.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import Any

import pandas as pd
import pytest
import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis.checks import CHECKS as ALL_CHECKS
from schemathesis.checks import not_a_server_error
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    positive_data_acceptance,
    response_schema_conformance,
    status_code_conformance,
)

from app import commands
from app.config import Settings, get_settings
from app.local_server import ServiceProcess
from app.main import create_app
from tests.app.conftest import AS_OF, START, bearer, flights, settings_for
from tests.app.servers import admin_headers, client, server
from tests.app.unstatable import refused_for_unstatable_rule

EXAMPLES = int(os.environ.get("FLEETPINN_FUZZ_EXAMPLES", "4"))
# Explicit examples and generated requests; the benchmark adds the coverage phase (boundary
# values of every parameter, hundreds of requests per operation).
PHASES = os.environ.get("FLEETPINN_FUZZ_PHASES", "examples,fuzzing").split(",")
# Where the benchmark collects one line per request (backend, role, operation, status, seconds)
# and one per server (backend, peak resident bytes) in LOG + ".rss".
LOG = os.environ.get("FLEETPINN_FUZZ_LOG")
ROLES = ("admin", "read")
# The server's address space: a request that tried to hold more fails inside it (a 500 here).
ADDRESS_SPACE_BYTES = 4 * 1024**3
# The service's own limit of a read (FLEETPINN_REQUEST_TIMEOUT_SECONDS' default): no answer
# may take longer, writes included.
TIME_LIMIT_S = Settings().request_timeout_seconds
# `python -m benchmarks.fuzz --checks all` adds every check schemathesis has (positive data
# accepted, negative data rejected, auth not ignored, ...; FLEETPINN_FUZZ_CHECKS=all), less
# those named in FLEETPINN_FUZZ_EXCLUDE (--exclude-checks: one check's finds, told apart).
_EXCLUDED = set(filter(None, os.environ.get("FLEETPINN_FUZZ_EXCLUDE", "").split(",")))
CHECKS = (
    [check for check in ALL_CHECKS.get_all() if check.__name__ not in _EXCLUDED]
    if os.environ.get("FLEETPINN_FUZZ_CHECKS") == "all"
    else [
        not_a_server_error,
        status_code_conformance,
        content_type_conformance,
        response_schema_conformance,
    ]
)


@pytest.fixture(scope="module")
def fuzzed(
    module_database_url: str, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[ServiceProcess]:
    """A server with tails N100..N102 (N100 inspected) and an active physics model, trained
    here; the server runs no jobs, so fuzzed retrains (up to 100,000 epochs) only queue."""
    running = server(
        module_database_url,
        tmp_path_factory.mktemp("fuzz"),
        address_space_bytes=ADDRESS_SPACE_BYTES,
        FLEETPINN_RUN_WORKER="0",
    )
    try:
        with client(running) as http:
            rows = [{"tail": f"N10{i}", **f} for i in range(3) for f in flights(40, stress=120.0)]
            csv = pd.DataFrame(rows).to_csv(index=False)
            answer = http.post("/flights/upload", files={"file": ("f.csv", csv, "text/csv")})
            assert answer.status_code == 201, answer.text
            inspection = {
                "inspection_id": "I1",
                "inspected_at": (START + pd.Timedelta(days=5)).isoformat(),
                "crack_length_m": 0.00502,
            }
            assert http.post("/aircraft/N100/inspections", json=inspection).status_code == 201
        outcome = commands.retrain({}, settings_for(module_database_url))
        assert outcome["status"] == "succeeded", outcome
        yield running
        if LOG:
            with open(f"{LOG}.rss", "a") as log:
                log.write(f"{_backend(module_database_url)}\t{running.peak_rss_bytes()}\n")
    finally:
        running.stop()


@pytest.fixture(scope="module", params=ROLES)
def caller(
    request: pytest.FixtureRequest, fuzzed: ServiceProcess, module_database_url: str
) -> tuple[str, dict[str, str]]:
    """(role, headers): the server's admin key, or a read key made for it."""
    if request.param == "admin":
        return "admin", admin_headers(fuzzed)
    settings = Settings(database_url=module_database_url)
    key = commands.create_key("read", "fuzz-read", replace=True, settings=settings).key
    return "read", bearer(key)


def _backend(database_url: str) -> str:
    return database_url.split(":")[0].split("+")[0]


def _published_schema() -> dict[str, Any]:
    """The schema the fuzzed server publishes at /openapi.json (test_health checks they are the
    same): its bounds come from its settings, whose today is the tests' (FLEETPINN_AS_OF)."""
    app = create_app()
    app.dependency_overrides[get_settings] = lambda: Settings(as_of=AS_OF)
    return app.openapi()


schema = schemathesis.openapi.from_dict(_published_schema())
schema.config.phases.update(phases=PHASES)


@schema.parametrize()
@settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,
    suppress_health_check=list(HealthCheck),
)
def test_no_server_error_and_every_answer_matches_its_schema(
    case: schemathesis.Case,
    fuzzed: ServiceProcess,
    caller: tuple[str, dict[str, str]],
    module_database_url: str,
) -> None:
    role, headers = caller
    response = case.call(base_url=fuzzed.base, headers=headers, timeout=2 * TIME_LIMIT_S)
    seconds = float(response.elapsed)
    if LOG:
        with open(LOG, "a") as log:
            backend = _backend(module_database_url)
            line = f"{backend}\t{role}\t{case.operation.label}\t{response.status_code}\t{seconds}"
            log.write(line + "\n")
    checks = CHECKS
    if refused_for_unstatable_rule(
        case.operation.label, response.status_code, _json_or_none(response)
    ):
        checks = [check for check in CHECKS if check.__name__ != positive_data_acceptance.__name__]
    if checks:  # none left: validate_response would run its defaults instead
        case.validate_response(response, checks=checks)
    assert seconds <= TIME_LIMIT_S, f"{case.operation.label} took {seconds:.1f} s"


def _json_or_none(response: object) -> object:
    try:
        return response.json()  # type: ignore[attr-defined]
    except ValueError:
        return None
