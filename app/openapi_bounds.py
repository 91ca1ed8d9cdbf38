"""The bounds that come from the settings, written into the OpenAPI schema of the process that
enforces them: a schema-valid request is then never refused for a bound the schema hides
(issue 42: `horizon_days=4811535` was schema-valid and answered 422).  The static bounds
(page sizes, offsets, versions) are the routes' own Query(le=...).  The as-of window's end
moves with today: the schema states it as of the day it was built, so it may say a day or two
less than the server later takes, never more."""

from __future__ import annotations

from typing import Any

from app.budget import as_of_window
from app.config import Settings
from app.date_window import date_window_pattern


def _record_bounds(settings: Settings) -> dict[str, dict[str, dict[str, float]]]:
    """{component: {property: JSON Schema bounds}} of the records' numbers as the ingest checks
    them (model.record_validation: > 0; app.services.records.plausibility: the settings' maxima, a
    tail's initial crack below the critical one)."""
    stress = {"exclusiveMinimum": 0, "maximum": settings.max_stress_range_mpa}
    crack = {"exclusiveMinimum": 0, "maximum": settings.max_crack_length_m}
    repaired = {"exclusiveMinimum": 0, "exclusiveMaximum": settings.critical_crack_m}
    inspection = {
        "crack_length_m": crack,
        "detection_threshold_m": crack,
        "pod_a50_m": crack,
        "pod_a90_m": crack,
        "crack_after_repair_m": repaired,
    }
    below_critical = {"exclusiveMinimum": 0, "exclusiveMaximum": settings.critical_crack_m}
    return {
        "AircraftIn": {"initial_crack_m": below_critical},
        "FlightIn": {"stress_range_mpa": stress},
        "FlightPatch": {"stress_range_mpa": stress},
        "InspectionIn": inspection,
        "InspectionPatch": inspection,
    }


def state_bounds(schema: dict[str, Any], settings: Settings) -> dict[str, Any]:
    """Write into `schema` (in place, and return it): horizon_days' maximum (max_horizon_days)
    wherever it is a query parameter or a body property, the most rows of a JSON batch of
    records (max_batch_rows) on every array request body, and the bounds of the records'
    lengths and stress ranges (_record_bounds), and the as-of window (app.budget.as_of_window)
    as a pattern of its dates (app.date_window)."""
    as_of = date_window_pattern(*as_of_window(settings))
    for operation in _operations(schema):
        for parameter in operation.get("parameters", []):
            if parameter.get("name") == "horizon_days":
                _set_integer(parameter.get("schema", {}), "maximum", settings.max_horizon_days)
            if parameter.get("name") == "as_of":
                for alternative in _alternatives(parameter.get("schema", {})):
                    if alternative.get("format") == "date":
                        alternative["pattern"] = as_of
        body = operation.get("requestBody", {}).get("content", {}).get("application/json", {})
        for alternative in _alternatives(body.get("schema", {})):
            if alternative.get("type") == "array":
                alternative["maxItems"] = settings.max_batch_rows
    components = schema.get("components", {}).get("schemas", {})
    for component in components.values():
        horizon = component.get("properties", {}).get("horizon_days")
        if horizon is not None and component.get("title", "").endswith("In"):
            _set_integer(horizon, "maximum", settings.max_horizon_days)
    for name, properties in _record_bounds(settings).items():
        declared = components.get(name, {}).get("properties", {})
        for field, bounds in properties.items():
            for alternative in _alternatives(declared.get(field, {})):
                if alternative.get("type") == "number":
                    alternative.update(bounds)
    return schema


def _operations(schema: dict[str, Any]) -> list[dict[str, Any]]:
    return [
        operation
        for path in schema.get("paths", {}).values()
        for operation in path.values()
        if isinstance(operation, dict)
    ]


def _alternatives(schema: dict[str, Any]) -> list[dict[str, Any]]:
    """The schema itself, or each of its anyOf alternatives (FastAPI writes `X | None` so)."""
    return list(schema.get("anyOf", [schema]))


def _set_integer(schema: dict[str, Any], key: str, value: int) -> None:
    for alternative in _alternatives(schema):
        if alternative.get("type") == "integer":
            alternative[key] = value
