"""The bounds that come from the settings, written into the OpenAPI schema of the process that
enforces them: a schema-valid request is then never refused for a bound the schema hides
(issue 42: `horizon_days=4811535` was schema-valid and answered 422).  The static bounds
(page sizes, offsets, versions) are the routes' own Query(le=...).  The as-of window's end
and the records' times' end move with today: the schema states them as of the day it was built,
so it may say a day or two less than the server later takes, never more.  The catalogue's
materials and a location's cracks against the model's come from the settings too."""

from __future__ import annotations

from datetime import UTC, date, datetime, timedelta
from typing import Any

from app.budget import as_of_window
from app.config import Settings
from app.date_window import date_window_pattern
from model.materials import law_for, materials


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
        # the bound is each cycle's (a flight's equivalent range of its cycles sums them)
        "CycleIn": {"stress_range_mpa": stress},
        "FlightPatch": {"stress_range_mpa": stress},
        "InspectionIn": inspection,
        "InspectionPatch": inspection,
    }


# Record times by component: a flight's and an inspection's time, sent or corrected.
_RECORD_TIMES = {
    "FlightIn": "flown_at",
    "FlightPatch": "flown_at",
    "InspectionIn": "inspected_at",
    "InspectionPatch": "inspected_at",
}
# The time of day after a record's date, as the server reads it (pydantic's speedate): hours to
# 23, minutes and seconds to 59 (no 24:00, no leap second), a fraction after "." or ",", and an
# offset Z or +-HH:MM (HHMM too) to 23:59.  RFC 3339 allows "t", "z", 24:00 leap seconds and
# offsets the server refuses, so `format: date-time` alone let schemathesis send them.
_TIME_OF_DAY = (
    "T([01][0-9]|2[0-3]):[0-5][0-9]:[0-5][0-9]([.,][0-9]+)?(Z|[+-]([01][0-9]|2[0-3]):?[0-5][0-9])$"
)
# The first day pandas' nanosecond times hold whole (model.record_validation refuses earlier).
_FIRST_PANDAS_DAY = date(1678, 1, 1)


def record_time_window(settings: Settings, now: datetime | None = None) -> tuple[date, date]:
    """The days a record's time may fall on (app.services.records.plausibility): from
    earliest_record_date to the day of now + clock_skew_seconds, UTC."""
    now = now or datetime.now(UTC)
    latest = (now + timedelta(seconds=settings.clock_skew_seconds)).astimezone(UTC).date()
    return max(settings.earliest_record_date, _FIRST_PANDAS_DAY), latest


def state_bounds(schema: dict[str, Any], settings: Settings) -> dict[str, Any]:
    """Write into `schema` (in place, and return it): horizon_days' maximum (max_horizon_days)
    wherever it is a query parameter or a body property, the most rows of a JSON batch of
    records (max_batch_rows) on every array request body, and the bounds of the records'
    lengths and stress ranges (_record_bounds), and the as-of window (app.budget.as_of_window)
    and the records' times (record_time_window) as patterns of their dates (app.date_window),
    a record time's followed by the times of day the server reads (_TIME_OF_DAY).
    A record time's pattern reads the date written, the check its UTC instant: an offset can
    move a time across the window's first or last day (a time later today than now + the
    clock skew is schema-valid and refused, as one in 8560 was before)."""
    as_of = date_window_pattern(*as_of_window(settings))
    record_time = date_window_pattern(*record_time_window(settings)).removesuffix("$")
    record_time += _TIME_OF_DAY
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
    location = components.get("LocationIn")
    if location is not None:
        location.setdefault("allOf", []).append(_location_cracks(settings))
        location["allOf"].append(_nasgro_terms(settings))
        for alternative in _alternatives(location.get("properties", {}).get("material", {})):
            if alternative.get("type") == "string":
                alternative["enum"] = list(materials(settings.materials_file))
    for name, field in _RECORD_TIMES.items():
        declared = components.get(name, {}).get("properties", {})
        for alternative in _alternatives(declared.get(field, {})):
            if alternative.get("format") == "date-time":
                alternative["pattern"] = record_time
    for name, properties in _record_bounds(settings).items():
        declared = components.get(name, {}).get("properties", {})
        for field, bounds in properties.items():
            for alternative in _alternatives(declared.get(field, {})):
                if alternative.get("type") == "number":
                    alternative.update(bounds)
    return schema


def _location_cracks(settings: Settings) -> dict[str, Any]:
    """A location's initial and critical crack, either given alone, against the model's other one
    (app.services.records.locations: an initial crack below the model's critical one, a critical
    crack above its initial one); both given, they compare with each other, which JSON Schema
    cannot state.  One anyOf of three cases: a generator expands each top-level anyOf into the
    others, so the fewer the better."""
    law = settings.law()
    number = {"type": "number"}
    null = {"type": "null"}
    initial_below = {"anyOf": [null, {**number, "exclusiveMaximum": law.critical_crack_m}]}
    critical_above = {**number, "exclusiveMinimum": law.initial_crack_m}
    return {
        "anyOf": [
            {
                "required": ["initial_crack_m", "critical_crack_m"],
                "properties": {"initial_crack_m": number, "critical_crack_m": number},
            },
            {"properties": {"initial_crack_m": initial_below, "critical_crack_m": null}},
            {
                "required": ["critical_crack_m"],
                "properties": {"initial_crack_m": null, "critical_crack_m": critical_above},
            },
        ]
    }


def _nasgro_terms(settings: Settings) -> dict[str, Any]:
    """A growth law nasgro only with a material whose row has NASGRO's terms (the entry's, or
    the settings' where the entry names none): app.routes.locations' check."""
    base = settings.law()
    with_terms = [
        name
        for name in materials(settings.materials_file)
        if law_for(name, base, settings.materials_file).nasgro is not None
    ]
    # an enum of the other laws, not a `not`: a generator reads it without expanding
    not_nasgro = {"properties": {"growth_law": {"properties": {"law": {"enum": _NOT_NASGRO}}}}}
    if base.nasgro is not None:
        return {"anyOf": [not_nasgro, {"properties": {"material": {"enum": [*with_terms, None]}}}]}
    if not with_terms:  # no row has the terms (the shipped table): no nasgro law
        return not_nasgro
    with_material = {"required": ["material"], "properties": {"material": {"enum": with_terms}}}
    return {"anyOf": [not_nasgro, with_material]}


_NOT_NASGRO = ["paris", "walker"]


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
