"""A crack case from the catalogue's JSON: built, round-tripped, and refused naming the
dimension at fault."""

from __future__ import annotations

import pytest

from model.crack_cases import CrackCaseError, case_from_dict
from model.crack_cases.centre import CentreCrack
from model.crack_cases.table import UserTable


def test_case_from_dict_names_the_dimension() -> None:
    case = case_from_dict({"type": "centre_crack", "width_m": 0.3})
    assert case == CentreCrack(0.3)
    assert case_from_dict(case.to_dict()) == case
    table = case_from_dict(
        {"type": "table", "crack_length_m": [0.001, 0.01], "beta_values": [1, 2]}
    )
    assert isinstance(table, UserTable)
    for data, field in (
        ({"type": "centre"}, "type"),
        ({"type": "centre_crack"}, "width_m"),
        ({"type": "centre_crack", "width_m": -1.0}, "width_m"),
        ({"type": "centre_crack", "width_m": 0.2, "depth_m": 1.0}, "depth_m"),
        ({"type": "surface_crack", "thickness_m": 0.01, "width_m": 0.1, "aspect_ratio": 3}, "aspect_ratio"),
        ({"type": "corner_crack_at_hole", "hole_diameter_m": 0.001, "thickness_m": 0.01,
          "width_m": 0.1, "aspect_ratio": 1.0}, "hole_diameter_m"),
        ({"type": "through_crack_at_hole", "hole_diameter_m": 0.01, "width_m": 0.015}, "width_m"),
        ({"type": "surface_crack", "thickness_m": 0.01, "width_m": 0.1, "aspect_ratio": "0.5"},
         "aspect_ratio"),
        ({"type": "through_crack_at_hole", "hole_diameter_m": 0.01, "cracks": True}, "cracks"),
        ({"type": "surface_crack", "thickness_m": 0.01, "width_m": 0.1, "aspect_ratio": 0.5,
          "growth_exponent": 3.0}, "shape_at_depth_m"),
    ):  # fmt: skip
        with pytest.raises(CrackCaseError) as caught:
            case_from_dict(data)
        assert caught.value.field == field, (data, str(caught.value))
