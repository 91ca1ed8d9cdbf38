"""Inputs that once answered 500 or were stored though implausible (issue 19): each is now a 422
naming the field and the problem, and nothing changes."""

from __future__ import annotations

import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import quote

import jsonschema_rs
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from fastapi.testclient import TestClient
from schemathesis.core.jsonschema.patterns import compile_ecma_pattern

from tests.app.conftest import flights, serving, settings_in

JSON = {"content-type": "application/json"}


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """A SQLite file with tail H1 (10 flights, F0001..) and one inspection, I1."""
    with serving(settings_in(Path(tmp_path_factory.mktemp("hostile")))) as test_client:
        assert test_client.put("/aircraft/H1").status_code == 201
        assert test_client.post("/aircraft/H1/flights", json=flights(10)).status_code == 201
        inspection = {
            "inspection_id": "I1",
            "inspected_at": "2024-01-02T00:00:00Z",
            "crack_length_m": 0.0051,
        }
        assert test_client.post("/aircraft/H1/inspections", json=inspection).status_code == 201
        yield test_client


def _refused(answer: Any, loc: list[Any], words: str) -> None:
    assert answer.status_code == 422, answer.text
    first = answer.json()["detail"][0]
    assert first["loc"] == loc, first
    assert words in first["msg"], first


def test_a_nan_initial_crack_is_a_422_that_encodes(client: TestClient) -> None:
    for value in ("NaN", "Infinity", "-Infinity"):
        answer = client.put("/aircraft/H1", content=f'{{"initial_crack_m": {value}}}', headers=JSON)
        _refused(answer, ["body", "initial_crack_m"], "finite number")
        assert answer.json()["detail"][0]["input"] in ("nan", "inf", "-inf")
    assert client.get("/aircraft/H1").json()["initial_crack_m"] is None


def test_a_null_date_in_a_correction_is_a_422(client: TestClient) -> None:
    answer = client.patch("/aircraft/H1/flights/F0001", json={"flown_at": None})
    _refused(answer, ["body", "flown_at"], "may not be null")
    answer = client.patch("/aircraft/H1/flights/F0001", json={"stress_range_mpa": None})
    _refused(answer, ["body", "stress_range_mpa"], "may not be null")
    for field in ("inspected_at", "detected", "repaired"):
        answer = client.patch("/aircraft/H1/inspections/I1", json={field: None})
        _refused(answer, ["body", field], "may not be null")
    assert client.get("/aircraft/H1/flights/F0001").json()["flown_at"].startswith("2024-01-01")
    # null still clears what may be cleared
    assert client.patch("/aircraft/H1/flights/F0002", json={"mission": None}).status_code == 200


@pytest.mark.parametrize("value", [0, 1700000000, 1.5, "0", "1700000000"])
def test_a_number_is_no_time(client: TestClient, value: Any) -> None:
    body = [{"flight_id": "N", "flown_at": value, "stress_range_mpa": 100.0}]
    _refused(client.post("/aircraft/H1/flights", json=body), ["body", 0, "flown_at"], "ISO 8601")
    answer = client.patch("/aircraft/H1/inspections/I1", json={"inspected_at": value})
    _refused(answer, ["body", "inspected_at"], "ISO 8601")
    answer = client.get("/aircraft/H1/forecast", params={"as_of": value})
    _refused(answer, ["query", "as_of"], "ISO 8601")
    assert client.get("/aircraft/H1").json()["flight_count"] == 10


def test_records_before_the_earliest_record_date_are_refused(client: TestClient) -> None:
    body = [{"flight_id": "OLD", "flown_at": "1900-01-01T00:00:00Z", "stress_range_mpa": 100.0}]
    answer = client.post("/aircraft/H1/flights", json=body)
    assert answer.status_code == 422
    assert answer.json()["column"] == "flown_at"
    assert "before 1950-01-01 (FLEETPINN_EARLIEST_RECORD_DATE)" in answer.json()["reason"]
    old = {"inspection_id": "OLD", "inspected_at": "1949-12-31T23:59:59Z", "crack_length_m": 0.005}
    answer = client.post("/aircraft/H1/inspections", json=old)
    assert answer.status_code == 422 and answer.json()["column"] == "inspected_at"
    answer = client.patch("/aircraft/H1/flights/F0001", json={"flown_at": "1901-05-01T00:00:00Z"})
    assert answer.status_code == 422 and answer.json()["column"] == "flown_at"
    csv = "tail,flight_id,flown_at,stress_range_mpa\nH1,OLD,1949-06-01T00:00:00Z,100\n"
    answer = client.post("/flights/upload", files={"file": ("old.csv", csv, "text/csv")})
    assert answer.status_code == 422 and answer.json()["row"] == 1
    assert client.get("/aircraft/H1").json()["flight_count"] == 10
    fine = [{"flight_id": "F1950", "flown_at": "1950-01-01T00:00:00Z", "stress_range_mpa": 100.0}]
    assert client.post("/aircraft/H2/flights", json=fine).status_code == 404  # unknown tail


def test_as_of_outside_its_window_is_a_422_naming_it(client: TestClient) -> None:
    # the tests' today is 2024-01-01 (FLEETPINN_AS_OF); the window reaches 3650 days beyond it
    for path in ("/aircraft/H1/forecast", "/fleet/ranking", "/forecasts"):
        for as_of in ("2400-01-01", "1949-12-31", "2033-12-30"):
            answer = client.get(path, params={"as_of": as_of})
            _refused(answer, ["query", "as_of"], "must lie in [1950-01-01, 2033-12-29]")
    answer = client.post("/aircraft/H1/forecast", params={"as_of": "2600-01-01"}, json={})
    _refused(answer, ["query", "as_of"], "FLEETPINN_MAX_HORIZON_DAYS")


def test_a_tail_is_refused_exactly_where_its_pattern_says(client: TestClient) -> None:
    """The tail pattern read as schemathesis reads it (Python re.ASCII) and as JSON Schema does
    (jsonschema_rs) agrees with the server (pydantic's Rust engine) and with the uploads' strip:
    `\\S` let "K\\x85" through in Python, and the server refused it."""
    stated = next(
        p["schema"]["pattern"]
        for p in client.get("/openapi.json").json()["paths"]["/aircraft/{tail}"]["get"][
            "parameters"
        ]
        if p["name"] == "tail"
    )
    drawn_as = compile_ecma_pattern(stated)
    assert drawn_as is not None
    validator = jsonschema_rs.validator_for({"type": "string", "pattern": stated})
    tails = ["K\x85", "\u00a0K", "K\u2028", "K\x1f", "K\u3000", "K\t", "K\n", "A\nB"]
    tails += ["K", "N 100", "K\ufeff", "A\rB", "K\x14K"]
    for tail in tails:
        answer = client.get(f"/aircraft/{quote(tail, safe='')}")
        refused = answer.status_code == 422
        assert answer.status_code in (404, 422), (tail, answer.text)
        assert refused == (drawn_as.search(tail) is None), tail
        assert refused == (not validator.is_valid(tail)), tail
        assert refused == (tail.strip() != tail or "\n" in tail), tail


def test_the_schema_states_the_as_of_window(client: TestClient) -> None:
    """A JSON Schema date has no bounds, so schemathesis drew as_of 2400-01-01 as schema-valid
    and got a 422: the schema now states the window as a pattern of its dates (app.date_window),
    which every date the server takes matches and no date it refuses does."""
    schema = client.get("/openapi.json").json()
    operations = [op for path in schema["paths"].values() for op in path.values()]
    stated = [
        alternative
        for op in operations
        for p in op.get("parameters", [])
        if p["name"] == "as_of"
        for alternative in p["schema"]["anyOf"]
        if alternative.get("format") == "date"
    ]
    assert len(stated) >= 5 and len({a["pattern"] for a in stated}) == 1
    window = re.compile(stated[0]["pattern"])
    for as_of in ("1950-01-01", "2024-01-01", "2033-12-29", "1949-12-31", "2033-12-30"):
        answer = client.get("/fleet/ranking", params={"as_of": as_of})
        assert answer.status_code in (200, 409, 422), answer.text
        assert (answer.status_code != 422) == bool(window.fullmatch(as_of)), as_of


def test_mission_shares_must_be_finite_and_bounded(client: TestClient) -> None:
    missions = [{"stress_range_mpa": 100.0, "share": 1e308}] * 2
    body = {"planned": {"flights_per_day": 4.0, "missions": missions}}
    answer = client.post("/aircraft/H1/forecast", json=body)
    _refused(answer, ["body", "planned", "missions", 0, "share"], "less than or equal to 1000000")
    text = (
        '{"planned": {"flights_per_day": 4, "missions": [{"stress_range_mpa": 100, "share": NaN}]}}'
    )
    answer = client.post("/aircraft/H1/forecast", content=text, headers=JSON)
    _refused(answer, ["body", "planned", "missions", 0, "share"], "finite number")


def test_retrain_networks_are_bounded(client: TestClient) -> None:
    answer = client.post("/models/retrain", json={"hidden": [[2480516, "elu"]]})
    _refused(answer, ["body", "hidden", 0, 0], "less than or equal to 64")
    answer = client.post("/models/retrain", json={"hidden": [[64, "tanh"]] * 4})
    _refused(answer, ["body", "hidden"], "12737 weights, at most 2000")
    answer = client.post("/models/retrain", json={"hidden": [[5, "tanh"]] * 5})
    _refused(answer, ["body", "hidden"], "at most 4 items")
    assert client.get("/jobs").json() == []


def test_a_csv_header_of_a_million_columns_is_refused_saying_so(client: TestClient) -> None:
    wide = ",".join(f"c{i}" for i in range(1_000_000)) + "\n"
    answer = client.post("/flights/upload", files={"file": ("wide.csv", wide, "text/csv")})
    assert answer.status_code == 422
    assert "header line longer than 65536 bytes" in answer.json()["reason"]
    many = ",".join(f"c{i}" for i in range(300)) + "\n" + ",".join("1" * 300) + "\n"
    answer = client.post("/flights/upload", files={"file": ("many.csv", many, "text/csv")})
    assert answer.status_code == 422
    assert "header names 300 columns, at most 256" in answer.json()["reason"]


def _upload(client: TestClient, name: str, content: bytes | str) -> Any:
    started = time.monotonic()
    answer = client.post("/flights/upload", files={"file": (name, content, "text/csv")})
    assert time.monotonic() - started < 5.0, "the shape must be refused before it is parsed"
    return answer


@pytest.mark.parametrize("extra", [40_000, 1_000_000])
def test_a_row_of_many_fields_is_refused_at_once_naming_it(client: TestClient, extra: int) -> None:
    """The probe's 40,000 extra fields took 31 s (pandas read them as an index of 40,000
    levels), a million had no answer after 120 s."""
    header = "tail,flight_id,flown_at,stress_range_mpa\n"
    csv = header + "H1,W1,2024-03-01T00:00:00Z,100" + ",1" * extra + "\n"
    answer = _upload(client, "wide_row.csv", csv)
    assert answer.status_code == 422, answer.text
    assert answer.json()["row"] == 1
    assert "more than the header's 4" in answer.json()["reason"]
    assert client.get("/aircraft/H1").json()["flight_count"] == 10


def test_a_parquet_bomb_is_refused_from_its_footer(client: TestClient, tmp_path: Path) -> None:
    """50 M identical rows in 0.75 MB of zstd Parquet took the server to 2.6 GiB."""
    rows = 1_000_000
    codes = pa.array(np.zeros(rows, dtype=np.int32))
    table = pa.table(
        {
            "tail": pa.DictionaryArray.from_arrays(codes, pa.array(["B1"])),
            "flight_id": pa.DictionaryArray.from_arrays(codes, pa.array(["F1"])),
            "flown_at": pa.DictionaryArray.from_arrays(codes, pa.array(["2024-01-01T00:00:00Z"])),
            "stress_range_mpa": pa.array(np.full(rows, 100.0)),
        }
    )
    path = tmp_path / "bomb.parquet"
    with pq.ParquetWriter(path, table.schema, compression="zstd") as writer:
        for _ in range(50):
            writer.write_table(table)
    answer = _upload(client, "bomb.parquet", path.read_bytes())
    assert answer.status_code == 422, answer.text
    reason = answer.json()["reason"]
    assert "50000000 rows, more than 1000000 (FLEETPINN_MAX_UPLOAD_ROWS)" in reason
    assert client.get("/aircraft/B1").status_code == 404


@pytest.mark.parametrize(
    ("method", "path", "allow"),
    [
        ("POST", "/aircraft/H1", "GET, PUT, DELETE"),
        ("PUT", "/aircraft/H1/forecast", "GET, POST"),
        ("POST", "/aircraft/H1/flights/F0001", "GET, PATCH, DELETE"),
        ("PUT", "/aircraft/H1/inspections/I1", "GET, PATCH, DELETE"),
        ("DELETE", "/aircraft/H1/inspections", "GET, POST"),
        ("GET", "/models/retrain", "POST"),
        ("PUT", "/models/1", "GET"),
    ],
)
def test_405_names_every_method_of_the_path(
    client: TestClient, method: str, path: str, allow: str
) -> None:
    answer = client.request(method, path)
    assert answer.status_code == 405, answer.text
    assert answer.headers["allow"] == allow


def test_an_offset_past_32_bits_is_a_422_naming_it(client: TestClient) -> None:
    """GET /audit?offset=9223372036854775808 answered 500 (no upper bound, where /aircraft
    stops at 2^31 - 1)."""
    for path in ("/audit", "/aircraft"):
        for offset in (9223372036854775808, 2**31):
            answer = client.get(path, params={"offset": offset})
            _refused(answer, ["query", "offset"], "less than or equal to 2147483647")
        assert client.get(path, params={"offset": 2**31 - 1}).status_code == 200


@pytest.mark.parametrize(
    ("method", "path", "body", "loc"),
    [
        ("POST", "/models/retrain", {"seed": False}, ["body", "seed"]),
        ("POST", "/models/retrain", {"epochs": "5"}, ["body", "epochs"]),
        ("POST", "/models/retrain", {"activate": 1}, ["body", "activate"]),
        ("POST", "/aircraft/H1/forecast", {"horizon_days": True}, ["body", "horizon_days"]),
        ("PUT", "/aircraft/H1", {"initial_crack_m": True}, ["body", "initial_crack_m"]),
        ("PATCH", "/aircraft/H1/inspections/I1", {"detected": "no"}, ["body", "detected"]),
        (
            "PATCH",
            "/aircraft/H1/flights/F0001",
            {"stress_range_mpa": "90"},
            ["body", "stress_range_mpa"],
        ),
        ("POST", "/models/retrain", {"epochs": 5.5}, ["body", "epochs"]),
    ],
)
def test_json_booleans_numbers_and_text_are_not_each_other(
    client: TestClient, method: str, path: str, body: dict[str, Any], loc: list[str]
) -> None:
    """Pydantic's lax mode took {"seed": false} as seed 0 (202) and "detected": "no" as false."""
    answer = client.request(method, path, json=body)
    assert answer.status_code == 422, answer.text
    assert answer.json()["detail"][0]["loc"] == loc
    assert client.get("/jobs").json() == []
    assert client.get("/aircraft/H1").json()["initial_crack_m"] is None
    assert client.get("/aircraft/H1/inspections/I1").json()["detected"] is True
    assert client.get("/aircraft/H1/flights/F0001").json()["stress_range_mpa"] == 100.0
    # an integer is a number: a float field takes it
    answer = client.patch("/aircraft/H1/flights/F0001", json={"stress_range_mpa": 100})
    assert answer.status_code == 200 and answer.json()["stress_range_mpa"] == 100.0


def test_a_number_without_a_fraction_is_an_integer(client: TestClient) -> None:
    """JSON Schema's integer takes 26.0 (schemathesis sent it as schema-valid): a 422 refused
    it.  A fraction, a boolean and text are still refused.  (No model is active here: a valid
    horizon gets the 409 that says so.)"""
    whole = client.post("/aircraft/H1/forecast", json={"horizon_days": 26})
    assert whole.status_code == 409, whole.text
    answer = client.post("/aircraft/H1/forecast", json={"horizon_days": 26.0})
    assert (answer.status_code, answer.json()) == (409, whole.json())
    for refused in (26.5, True, "26"):
        answer = client.post("/aircraft/H1/forecast", json={"horizon_days": refused})
        assert answer.status_code == 422, (refused, answer.text)
        assert answer.json()["detail"][0]["loc"] == ["body", "horizon_days"]


def test_every_bound_is_written_as_json_schema_reads_it(client: TestClient) -> None:
    """Bounds put on top of a validator were written as pydantic's own `ge`/`le` keys, which
    JSON Schema does not know: schemathesis sent model_version 3.4e21 as schema-valid."""

    def raw_keys(node: Any) -> list[str]:
        if isinstance(node, dict):
            found = [k for k in node if k in ("ge", "le", "gt", "lt")]
            return found + [k for v in node.values() for k in raw_keys(v)]
        if isinstance(node, list):
            return [k for v in node for k in raw_keys(v)]
        return []

    schema = client.get("/openapi.json").json()
    assert raw_keys(schema) == []
    batch = schema["components"]["schemas"]["ForecastBatchIn"]["properties"]["model_version"]
    assert batch["anyOf"][0] == {"type": "integer", "minimum": 1, "maximum": 2**31 - 1}
    initial = schema["components"]["schemas"]["AircraftIn"]["properties"]["initial_crack_m"]
    assert initial["anyOf"][0]["exclusiveMaximum"] == 0.05  # the critical crack (setting)
    answer = client.put("/aircraft/H1", json={"initial_crack_m": 0.05})
    assert answer.status_code == 422 and answer.json()["column"] == "initial_crack_m"
    assert "must be < the critical crack (0.05 m)" in answer.json()["reason"]
    hidden = schema["components"]["schemas"]["RetrainIn"]["properties"]["hidden"]
    units = hidden["anyOf"][0]["items"]["prefixItems"][0]
    assert (units["minimum"], units["maximum"]) == (1, 64)


def test_the_schema_states_the_settings_bounds(client: TestClient) -> None:
    """horizon_days=4811535 was schema-valid and answered 422: the schema now says 3650."""
    schema = client.get("/openapi.json").json()
    parameters = schema["paths"]["/fleet/ranking"]["get"]["parameters"]
    horizon = next(p for p in parameters if p["name"] == "horizon_days")["schema"]["anyOf"][0]
    assert horizon == {"type": "integer", "minimum": 1, "maximum": 3650}
    body = schema["components"]["schemas"]["ForecastIn"]["properties"]["horizon_days"]
    assert body["maximum"] == 3650
    flights = schema["paths"]["/aircraft/{tail}/flights"]["post"]["requestBody"]
    assert flights["content"]["application/json"]["schema"]["maxItems"] == 50_000
    audit = schema["paths"]["/audit"]["get"]["parameters"]
    offset = next(p for p in audit if p["name"] == "offset")["schema"]
    assert offset["maximum"] == 2**31 - 1
    answer = client.get("/fleet/ranking", params={"horizon_days": 3651})
    _refused(answer, ["query", "horizon_days"], "less than or equal to 3650")
    components = schema["components"]["schemas"]
    stress = components["FlightIn"]["properties"]["stress_range_mpa"]["anyOf"][0]
    assert stress == {"type": "number", "exclusiveMinimum": 0, "maximum": 1000.0}
    crack = components["InspectionPatch"]["properties"]["pod_a90_m"]["anyOf"][0]
    assert crack == {"type": "number", "exclusiveMinimum": 0, "maximum": 0.5}
    # the bounds stated are the ones enforced: just past each is refused
    body = [{"flight_id": "S", "flown_at": "2024-01-05T00:00:00Z", "stress_range_mpa": 1000.5}]
    answer = client.post("/aircraft/H1/flights", json=body)
    assert answer.status_code == 422 and "FLEETPINN_MAX_STRESS_RANGE_MPA" in answer.json()["reason"]


def test_a_422_quotes_a_prefix_of_a_long_input(client: TestClient) -> None:
    """A 10 MB field was echoed back whole."""
    long = "7" * 10_000_000
    answer = client.put("/aircraft/H1", json={"initial_crack_m": long})
    assert answer.status_code == 422
    assert len(answer.content) < 5_000
    quoted = answer.json()["detail"][0]["input"]
    assert quoted == "7" * 200 + "… (10000000 characters)"
    body = [{"flight_id": "L", "flown_at": long, "stress_range_mpa": 100.0}]
    answer = client.post("/aircraft/H1/flights", json=body)
    assert answer.status_code == 422 and len(answer.content) < 5_000
    assert "(10000000 characters)" in answer.json()["detail"][0]["msg"]
    # a batch of many bad rows: the first 100 errors, each input cut to 10 items
    rows = [{"flight_id": "B", "flown_at": 0, "stress_range_mpa": 1.0}] * 1000
    answer = client.post("/aircraft/H1/flights", json=rows)
    assert answer.status_code == 422 and len(answer.json()["detail"]) == 100
    answer = client.put("/aircraft/H1", json=list(range(1000)))
    assert answer.json()["detail"][0]["input"][-1] == "… (1000 items)"
    assert client.get("/aircraft/H1").json()["flight_count"] == 10


def test_a_kept_field_is_stated_never_null(client: TestClient) -> None:
    """schemathesis' positive data: a correction's kept fields were stated nullable while null
    is refused (PATCH {"stress_range_mpa": null} -> 422)."""
    components = client.get("/openapi.json").json()["components"]["schemas"]
    for model, field in (
        ("FlightPatch", "flown_at"),
        ("FlightPatch", "stress_range_mpa"),
        ("InspectionPatch", "inspected_at"),
        ("InspectionPatch", "detected"),
        ("InspectionPatch", "repaired"),
    ):
        stated = components[model]["properties"][field]
        assert "anyOf" not in stated and stated["type"] != "null", (model, stated)
        path = (
            "/aircraft/H1/flights/F0001"
            if model == "FlightPatch"
            else ("/aircraft/H1/inspections/I1")
        )
        _refused(client.patch(path, json={field: None}), ["body", field], "may not be null")
    # a field null clears is stated nullable still
    cleared = components["InspectionPatch"]["properties"]["crack_length_m"]["anyOf"]
    assert {"type": "null"} in cleared
