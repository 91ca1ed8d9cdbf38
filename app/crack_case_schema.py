"""A location's crack_case (PUT /locations) and its JSON schema: one branch per case of
model.crack_cases, each with its type, its dimensions and their bounds (issue 42: the schema said
only `{"type": string}` and any other key, so a schema-valid case was refused for a dimension
the schema hid).

The dimensions and what is required come from the cases' dataclass fields; the bounds a case
checks on one value (a length > 0, an aspect ratio's range, 1 or 2 cracks, a method's names)
are written here beside them, and tests/app/test_crack_case_schema.py builds each case at and
past each bound, so the two cannot part.  What compares two dimensions (a hole's diameter
against the width, a corner crack's radius against the thickness, the evolving shape's depth
below the thickness, a table's increasing lengths, one beta per length) JSON Schema cannot
state: the case's check refuses it with a 422 naming the dimension, as the description says.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import Any, Literal

from pydantic import BaseModel, Field, model_validator

from app import schema_examples as ex
from app.schema_rules import with_rules
from model.crack_cases import CASES, CrackCaseError, case_from_dict
from model.geometry import MAX_POINTS

# The one-value bounds a case checks (model.crack_cases' _check), by (type, dimension).
_BOUNDS: dict[tuple[str, str], dict[str, Any]] = {
    ("corner_crack_at_hole", "aspect_ratio"): {"minimum": 0.2, "maximum": 2.0},
    ("surface_crack", "aspect_ratio"): {"exclusiveMinimum": 0, "maximum": 2.0},
    ("surface_crack", "growth_exponent"): {"minimum": 1.0, "maximum": 10.0},
}
# A case's crack count: one crack or two, diametrically opposite.
_CRACKS = {"type": "integer", "enum": [1, 2]}
_LENGTH = {"type": "number", "exclusiveMinimum": 0}
_NULL = {"type": "null"}
# A dimension that needs another (model.crack_cases.surface: an evolving shape needs its depth).
_NEEDS = {"surface_crack": {"growth_exponent": "shape_at_depth_m"}}


def state_crack_cases(schema: dict[str, Any]) -> None:
    """The crack case's JSON schema (a rule of app.schema_rules.with_rules): one of the cases'
    branches, in place of pydantic's `type` and any other key."""
    for key in ("properties", "required", "additionalProperties"):
        schema.pop(key, None)
    schema["oneOf"] = crack_case_branches()


def crack_case_branches() -> list[dict[str, Any]]:
    """One JSON schema per crack case: {"type": const, dimensions...}, nothing else."""
    return [_branch(name, case) for name, case in CASES.items()]


def _branch(name: str, case: type) -> dict[str, Any]:
    hints = typing.get_type_hints(case)
    properties: dict[str, Any] = {"type": {"const": name}}
    required = ["type"]
    for field in dataclasses.fields(case):
        properties[field.name] = _dimension(name, field.name, hints[field.name])
        if field.default is dataclasses.MISSING and field.default_factory is dataclasses.MISSING:
            required.append(field.name)
        elif field.default is not None:
            properties[field.name]["default"] = field.default
    branch: dict[str, Any] = {
        "title": name,
        "type": "object",
        "properties": properties,
        "required": required,
        "additionalProperties": False,
    }
    for dimension, needed in _NEEDS.get(name, {}).items():
        # `dimension` null or left out, or `needed` given (not null) beside it
        given = {"required": [needed], "properties": {needed: {"not": _NULL}}}
        left_out = {"properties": {dimension: _NULL}}
        branch.setdefault("allOf", []).append({"anyOf": [left_out, given]})
    return branch


def _dimension(case: str, name: str, hint: Any) -> dict[str, Any]:
    """The schema of one dimension from its annotation (float, int, Literal, tuple of floats, or
    one of those or None)."""
    options = typing.get_args(hint) if isinstance(hint, types.UnionType) else (hint,)
    given = [option for option in options if option is not type(None)]
    assert len(given) == 1, f"{case}.{name}: one type or None, got {hint}"
    schema = _one(case, name, given[0])
    return {"anyOf": [schema, _NULL]} if len(given) < len(options) else schema


def _one(case: str, name: str, hint: Any) -> dict[str, Any]:
    if typing.get_origin(hint) is Literal:
        return {"type": "string", "enum": list(typing.get_args(hint))}
    if typing.get_origin(hint) is tuple:
        # a table's lengths and betas: 2 to 64 values > 0 each (model.geometry.GeometryTable)
        items = {"type": "number", "exclusiveMinimum": 0}
        return {"type": "array", "items": items, "minItems": 2, "maxItems": MAX_POINTS}
    if hint is int:
        assert name == "cracks", f"{case}.{name}: an integer dimension other than cracks"
        return dict(_CRACKS)
    assert hint is float, f"{case}.{name}: {hint}"
    if name.endswith("_m"):
        return dict(_LENGTH)
    return {"type": "number", **_BOUNDS[(case, name)]}


CRACK_CASE_EXAMPLE: ex.Example = {
    "type": "through_crack_at_hole",
    "hole_diameter_m": 0.0048,
    "cracks": 1,
    "width_m": 0.05,
}


class CrackCaseSpec(BaseModel):
    """A crack case of model.crack_cases by its type and dimensions (SI, m): centre_crack
    (width_m, method tada|feddersen), edge_crack (width_m, method tada|brown_srawley),
    through_crack_at_hole (hole_diameter_m, cracks 1|2, width_m or null), corner_crack_at_hole
    (hole_diameter_m, thickness_m, width_m, aspect_ratio a/c, cracks, point bore|surface),
    surface_crack (thickness_m, width_m, aspect_ratio, point depth|surface; growth_exponent
    and shape_at_depth_m to evolve its shape), table
    (crack_length_m, beta_values, width_m or null).  A dimension that is missing, unknown or
    out of the case's range is a 422 naming it; the schema states each case's dimensions and
    their bounds, not what compares two of them (a hole's diameter below half the width, a
    corner crack's radius 0.5-2 thicknesses, shape_at_depth_m below thickness_m, a table's
    increasing lengths with one beta each)."""

    model_config = with_rules(
        ex.examples(CRACK_CASE_EXAMPLE, extra="allow", allow_inf_nan=False), state_crack_cases
    )

    type: str = Field(max_length=64)

    @model_validator(mode="after")
    def _buildable(self) -> CrackCaseSpec:
        try:
            case_from_dict(self.model_dump())
        except CrackCaseError as exc:
            raise ValueError(f"crack_case.{exc.field or 'type'}: {exc}") from None
        return self
