"""A crack case's JSON schema (app.crack_case_schema) and the case's own checks
(model.crack_cases) agree on every dimension's bounds: at and past each bound, and a length of
0, the schema takes a case exactly where the case can be built."""

from __future__ import annotations

from typing import Any

import jsonschema_rs
import pytest

from app.crack_case_schema import CrackCaseSpec, crack_case_branches
from model.crack_cases import CASES, CrackCaseError, case_from_dict

VALID: dict[str, dict[str, Any]] = {
    "centre_crack": {"width_m": 0.2},
    "edge_crack": {"width_m": 0.1},
    "through_crack_at_hole": {"hole_diameter_m": 0.005, "width_m": 0.05},
    "corner_crack_at_hole": {
        "hole_diameter_m": 0.005,
        "thickness_m": 0.004,
        "width_m": 0.05,
        "aspect_ratio": 1.0,
    },
    "surface_crack": {"thickness_m": 0.01, "width_m": 0.1, "aspect_ratio": 0.5},
    "table": {"crack_length_m": [0.001, 0.05], "beta_values": [1.1, 1.3]},
}
# (type, dimension, value, whether the case takes it)
EDGES = [
    ("corner_crack_at_hole", "aspect_ratio", 0.2, True),
    ("corner_crack_at_hole", "aspect_ratio", 0.19, False),
    ("corner_crack_at_hole", "aspect_ratio", 2.0, True),
    ("corner_crack_at_hole", "aspect_ratio", 2.01, False),
    ("surface_crack", "aspect_ratio", 0.0, False),
    ("surface_crack", "aspect_ratio", 2.0, True),
    ("surface_crack", "aspect_ratio", 2.01, False),
    ("through_crack_at_hole", "cracks", 2, True),
    ("through_crack_at_hole", "cracks", 0, False),
    ("through_crack_at_hole", "cracks", True, False),
    ("corner_crack_at_hole", "cracks", 3, False),
    ("centre_crack", "method", "feddersen", True),
    ("centre_crack", "method", "brown_srawley", False),
    ("edge_crack", "method", "brown_srawley", True),
    ("surface_crack", "point", "surface", True),
    ("surface_crack", "point", "bore", False),
    ("centre_crack", "width_m", 0.0, False),
    ("through_crack_at_hole", "width_m", None, True),
    ("centre_crack", "width_m", None, False),
    ("table", "beta_values", [1.1, 0.0], False),
    ("table", "crack_length_m", [0.001], False),
    ("centre_crack", "thickness_m", 0.01, False),  # not a centre crack's dimension
]
EVOLVING = {"growth_exponent": 3.0, "shape_at_depth_m": 0.002}


def _builds(case: dict[str, Any]) -> bool:
    try:
        case_from_dict(case)
    except CrackCaseError:
        return False
    return True


def _schema_takes(case: dict[str, Any]) -> bool:
    return jsonschema_rs.validator_for({"oneOf": crack_case_branches()}).is_valid(case)


def test_every_case_has_one_branch_that_takes_its_valid_dimensions() -> None:
    assert [b["properties"]["type"]["const"] for b in crack_case_branches()] == list(CASES)
    for name, dimensions in VALID.items():
        case = {"type": name, **dimensions}
        assert _builds(case) and _schema_takes(case), name


@pytest.mark.parametrize(("name", "dimension", "value", "valid"), EDGES)
def test_the_schema_takes_a_dimension_where_the_case_does(
    name: str, dimension: str, value: object, valid: bool
) -> None:
    case = {"type": name, **VALID[name], dimension: value}
    assert _builds(case) == valid
    assert _schema_takes(case) == valid


@pytest.mark.parametrize(
    ("evolving", "valid"),
    [
        (EVOLVING, True),
        ({"growth_exponent": 3.0}, False),  # an evolving shape needs its depth
        ({"growth_exponent": 3.0, "shape_at_depth_m": None}, False),
        ({"growth_exponent": None, "shape_at_depth_m": None}, True),
        ({**EVOLVING, "growth_exponent": 0.9}, False),
        ({**EVOLVING, "growth_exponent": 10.0}, True),
    ],
)
def test_an_evolving_surface_crack_needs_its_depth(evolving: dict[str, Any], valid: bool) -> None:
    case = {"type": "surface_crack", **VALID["surface_crack"], **evolving}
    assert _builds(case) == valid
    assert _schema_takes(case) == valid


def test_the_published_schema_is_the_branches() -> None:
    assert CrackCaseSpec.model_json_schema()["oneOf"] == crack_case_branches()
