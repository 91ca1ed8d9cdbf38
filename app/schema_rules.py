"""Rules that span several fields of a request body, stated in its JSON schema where JSON Schema
can say them, so that a schema-valid body is not refused for a rule the schema hides (issue 42:
schemathesis' positive data sent a flight with two load forms, a location with both geometry
forms, a planned mix with every share 0).

A rule here only states what a validator already checks (the 422 stays, naming the field);
what compares two values (pod_a90_m > pod_a50_m, a cycle's max above its min) JSON Schema
cannot state, and stays said in the fields' descriptions.  A field left out and a field sent
as null are the same to these rules, as to the validators.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pydantic import ConfigDict

Rule = Callable[[dict[str, Any]], None]


def with_rules(config: ConfigDict, *rules: Rule) -> ConfigDict:
    """config (app.schema_examples.examples' model_config) whose JSON schema also states
    `rules`, each an allOf member."""
    extra = dict(config.get("json_schema_extra") or {})  # type: ignore[arg-type]

    def stated(schema: dict[str, Any]) -> None:
        schema.update(extra)
        for rule in rules:
            rule(schema)

    return ConfigDict(**{**config, "json_schema_extra": stated})


def exactly_one_of(*fields: str) -> Rule:
    """Exactly one of `fields` given (not null)."""

    def rule(schema: dict[str, Any]) -> None:
        branches = [
            {
                "required": [given],
                "properties": {
                    name: _given(schema, name) if name == given else _NULL for name in fields
                },
            }
            for given in fields
        ]
        schema.setdefault("allOf", []).append({"oneOf": branches})

    return rule


def at_most_one_of(*fields: str) -> Rule:
    """At most one of `fields` given (not null)."""

    def rule(schema: dict[str, Any]) -> None:
        branches = [
            {"properties": {name: _NULL for name in fields if name != kept}} for kept in fields
        ]
        schema.setdefault("allOf", []).append({"anyOf": branches})

    return rule


def only_with(field: str, needed: str) -> Rule:
    """`field` given only where `needed` is given too."""

    def rule(schema: dict[str, Any]) -> None:
        branches = [
            {"properties": {field: _NULL}},
            {"required": [needed], "properties": {needed: _given(schema, needed)}},
        ]
        schema.setdefault("allOf", []).append({"anyOf": branches})

    return rule


def not_together(**values: object) -> Rule:
    """Not every field of `values` at its value (each field's default differs from its value, so
    a field left out is not at it)."""

    def rule(schema: dict[str, Any]) -> None:
        branches = [{"properties": {name: {"not": {"const": v}}}} for name, v in values.items()]
        schema.setdefault("allOf", []).append({"anyOf": branches})

    return rule


def only_when(field: str, other: str, value: object) -> Rule:
    """`field` given only where `other` is `value` (sent: its default is not `value`)."""

    def rule(schema: dict[str, Any]) -> None:
        branches = [
            {"properties": {field: _NULL}},
            {"required": [other], "properties": {other: {"const": value}}},
        ]
        schema.setdefault("allOf", []).append({"anyOf": branches})

    return rule


GIVEN, ABSENT = "given", "absent"


def one_of_shapes(*shapes: dict[str, object]) -> Rule:
    """Exactly one of `shapes`, each {field: GIVEN, ABSENT or the value it must have}; a field
    whose default is that value may be left out."""

    def rule(schema: dict[str, Any]) -> None:
        branches = []
        for shape in shapes:
            properties: dict[str, Any] = {}
            required = []
            for name, form in shape.items():
                if form == ABSENT:
                    properties[name] = _NULL
                    continue
                if form == GIVEN:
                    properties[name] = _given(schema, name)
                else:
                    properties[name] = {"const": form}
                if form == GIVEN or schema["properties"][name].get("default") != form:
                    required.append(name)
            branches.append({"properties": properties, "required": required})
        schema.setdefault("allOf", []).append({"oneOf": branches})

    return rule


_NULL = {"type": "null"}


def _given(schema: dict[str, Any], name: str) -> dict[str, Any]:
    """The field's schema less its null alternative (a copy)."""
    declared = schema["properties"][name]
    kept = [a for a in declared.get("anyOf", [declared]) if a.get("type") != "null"]
    return dict(kept[0]) if len(kept) == 1 else {"anyOf": kept}
