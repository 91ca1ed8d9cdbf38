"""The catalogue of control points (PUT/GET /locations): request and answer shapes.

A physical value left null is the model's own (the service's settings), which is what the
default location holds, so a fleet with that one location answers as before locations.  Each
check names its field in the 422 (a critical crack at or below the initial one, a PoD a90 at or
below its a50), and nothing is stored.
"""

from __future__ import annotations

import itertools
from datetime import datetime
from typing import Annotated, Any, Literal

from fastapi import Path
from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_validator

from app import schema_examples as ex
from app.crack_case_schema import CrackCaseSpec
from app.schema_rules import (
    ABSENT,
    GIVEN,
    at_most_one_of,
    not_together,
    one_of_shapes,
    only_when,
    only_with,
    with_rules,
)
from app.tables import DEFAULT_LOCATION

LOCATION_NAME = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$"
LocationPath = Annotated[
    str,
    Path(
        pattern=LOCATION_NAME,
        description=f"Control point name (letters, digits, _ . -); '{DEFAULT_LOCATION}' is the "
        "one every request without a location names.",
    ),
]
LOCATION_IN: ex.Example = {
    "description": "Lower wing skin splice, stringer 12",
    "stress_factor": 1.35,
    "stress_factor_by_mission": {"M3": 1.5},
    "geometry_table": {"crack_length_m": [0.002, 0.02, 0.05], "factor": [1.12, 1.2, 1.45]},
    "initial_crack_m": 0.00127,
    "critical_crack_m": 0.04,
    "material": "2024-T3",
    "growth_law": {"law": "paris", "paris_c": 1.5e-11, "paris_m": 3.8},
    "inspection_method": "eddy current",
    "sizing_relative_sd": 0.05,
    "pod_a50_m": 0.0015,
    "pod_a90_m": 0.0025,
}
LOCATION_OUT: ex.Example = {
    "name": "wing-splice-12",
    **LOCATION_IN,
    "geometry_factor": None,
    "created_at": "2026-11-28T08:00:00Z",
    "updated_at": "2026-11-28T08:00:00Z",
}
_LENGTH = Field(default=None, gt=0, lt=1)


class GeometryTable(BaseModel):
    """The geometry factor F over crack length, interpolated linearly (held at the ends)."""

    model_config = ex.examples(
        {"crack_length_m": [0.002, 0.05], "factor": [1.12, 1.4]},
        extra="forbid",
        allow_inf_nan=False,
        strict=True,
    )

    crack_length_m: list[Annotated[float, Field(gt=0, lt=1)]] = Field(min_length=2, max_length=64)
    factor: list[Annotated[float, Field(gt=0, le=10)]] = Field(min_length=2, max_length=64)

    @field_validator("crack_length_m")
    @classmethod
    def _increasing(cls, lengths: list[float]) -> list[float]:
        if any(b <= a for a, b in itertools.pairwise(lengths)):
            raise ValueError("crack lengths must increase strictly")
        return lengths

    @field_validator("factor")
    @classmethod
    def _one_per_length(cls, factor: list[float], info: ValidationInfo) -> list[float]:
        lengths = info.data.get("crack_length_m")
        if lengths is not None and len(lengths) != len(factor):
            raise ValueError(f"one factor per crack length: {len(lengths)} lengths")
        return factor


class GrowthLaw(BaseModel):
    """The location's growth law (model.growth_laws): Paris' da/dN = C dK^m, Walker's (C, m
    and gamma: dK / (1 - R)**(1 - gamma)) or NASGRO's equation (its terms from the entry's
    material), with its constants (SI: m, MPa sqrt(m)), or learn: true to fit C and m (and
    Walker's gamma) to the location's inspections; neither: the entry's material's."""

    model_config = with_rules(
        ex.examples(
            {"law": "paris", "paris_c": 1.5e-11, "paris_m": 3.8},
            {"law": "paris", "learn": True},
            {"law": "walker", "paris_c": 1.5e-11, "paris_m": 3.8, "walker_gamma": 0.6},
            extra="forbid",
            allow_inf_nan=False,
            strict=True,
        ),
        one_of_shapes(
            {"learn": True, "paris_c": ABSENT, "paris_m": ABSENT, "walker_gamma": ABSENT},
            {"learn": False, "paris_c": GIVEN, "paris_m": GIVEN},
            {"learn": False, "paris_c": ABSENT, "paris_m": ABSENT},
        ),
        only_when("walker_gamma", "law", "walker"),
        not_together(law="nasgro", learn=True),
    )

    law: Literal["paris", "walker", "nasgro"] = "paris"
    paris_c: float | None = Field(default=None, gt=0, lt=1)
    paris_m: float | None = Field(default=None, gt=0, le=10)
    walker_gamma: float | None = Field(
        default=None, gt=0, le=1, description="Walker's gamma (law walker only)."
    )
    learn: bool = False

    @model_validator(mode="after")
    def _constants_or_learn(self) -> GrowthLaw:
        given = (self.paris_c is not None) + (self.paris_m is not None)
        if self.learn and (given or self.walker_gamma is not None):
            raise ValueError("either the constants, or learn: true")
        if given == 1:
            raise ValueError("both paris_c and paris_m, or learn: true")
        if self.walker_gamma is not None and self.law != "walker":
            raise ValueError(f"walker_gamma is Walker's constant, not the {self.law} law's")
        if self.law == "nasgro" and self.learn:
            raise ValueError("learn fits paris or walker, not the nasgro law")
        return self


def _constants_somewhere(schema: dict[str, Any]) -> None:
    """A growth law's C and m from somewhere (the _constants_somewhere check): the entry's
    material's, or the law's own, learnt or NASGRO's terms (one anyOf, its second branch's
    alternatives inside growth_law: a generator expands each top-level anyOf into the others)."""
    law = {
        "anyOf": [
            {"type": "null"},
            {"required": ["learn"], "properties": {"learn": {"const": True}}},
            {"required": ["paris_c"], "properties": {"paris_c": {"type": "number"}}},
            {"required": ["law"], "properties": {"law": {"const": "nasgro"}}},
        ]
    }
    branches = [
        {"required": ["material"], "properties": {"material": {"type": "string"}}},
        {"properties": {"growth_law": law}},
    ]
    schema.setdefault("allOf", []).append({"anyOf": branches})


class LocationIn(BaseModel):
    """A control point: its local stress per unit of the recorded load, its crack physics
    (null: the model's) and how it is inspected.  PUT replaces the whole entry."""

    # strict: a number sent as a string ("1.2") is refused, not read (nothing is stored)
    model_config = with_rules(
        ex.examples(LOCATION_IN, {}, extra="forbid", allow_inf_nan=False, strict=True),
        at_most_one_of("crack_case", "geometry_factor", "geometry_table"),
        only_with("limit_stress_mpa", "crack_case"),
        at_most_one_of("limit_stress_mpa", "critical_crack_m"),
        one_of_shapes(
            {"pod_a50_m": ABSENT, "pod_a90_m": ABSENT}, {"pod_a50_m": GIVEN, "pod_a90_m": GIVEN}
        ),
        _constants_somewhere,
    )

    description: str = Field(default="", max_length=2000)
    stress_factor: float = Field(
        default=1.0, gt=0, le=100, description="Local stress range per unit of the recorded one."
    )
    stress_factor_by_mission: dict[str, Annotated[float, Field(gt=0, le=100)]] | None = Field(
        default=None,
        max_length=256,
        description="Per mission name, its own factor (other missions: stress_factor).",
    )
    geometry_factor: float | None = Field(
        default=None, gt=0, le=10, description="A constant geometry factor F (null: the model's)."
    )
    geometry_table: GeometryTable | None = None
    initial_crack_m: float | None = _LENGTH
    critical_crack_m: float | None = _LENGTH
    material: str | None = Field(
        default=None,
        max_length=128,
        description="An alloy of the materials table (model/data/materials.csv and the rows "
        "of FLEETPINN_MATERIALS_FILE; another name is a 422): its C, m, gamma and NASGRO terms "
        "(a growth_law's own C and m override them).",
    )
    growth_law: GrowthLaw | None = None
    inspection_method: str | None = Field(default=None, max_length=128)
    sizing_relative_sd: float | None = Field(
        default=None, gt=0, le=1, description="Sizing error of the method, relative sd."
    )
    pod_a50_m: float | None = Field(
        default=None, gt=0, lt=1, description="Crack found with probability 0.5 (m)."
    )
    pod_a90_m: float | None = Field(
        default=None,
        gt=0,
        lt=1,
        # checked when absent too: pod_a50_m alone is refused here, not stored
        validate_default=True,
        description="Crack found with probability 0.9 (m); a log-odds curve in ln a through both.",
    )

    crack_case: CrackCaseSpec | None = Field(
        default=None,
        description="The location's crack case: beta(a) from its published solution, in "
        "place of geometry_factor or geometry_table (model.crack_cases).",
    )
    limit_stress_mpa: float | None = Field(
        default=None,
        gt=0,
        le=5000,
        description="The stress the part must carry (MPa): with a crack_case, a_crit is where "
        "K = beta S sqrt(pi a) reaches the toughness, or the net section yields, first "
        "(in place of critical_crack_m).",
    )
    fracture_toughness_mpa_sqrt_m: float | None = Field(
        default=None, gt=0, le=1000, description="K_c or K_IC (null: the material's)."
    )
    yield_strength_mpa: float | None = Field(
        default=None, gt=0, le=5000, description="For net-section yield (null: the material's)."
    )

    gamma_below_zero: float | None = Field(
        default=None,
        ge=0,
        le=1,
        description="Walker's gamma for cycles at R < 0 (growth law walker, cycle files). "
        "Null (the default): the material's gamma, as for R >= 0; 0: the compressive part of a "
        "cycle ignored (its rate a power of K_max alone, Dowling's practice).",
    )

    @model_validator(mode="after")
    def _crack_case_alone(self) -> LocationIn:
        given = self.crack_case is not None
        if given and (self.geometry_factor is not None or self.geometry_table is not None):
            raise ValueError(
                "crack_case: a crack case or geometry_factor / geometry_table, not both"
            )
        if self.limit_stress_mpa is not None and not given:
            raise ValueError("limit_stress_mpa: needs a crack_case to compute a_crit from")
        if self.limit_stress_mpa is not None and self.critical_crack_m is not None:
            raise ValueError("limit_stress_mpa: a limit stress or critical_crack_m, not both")
        return self

    @field_validator("geometry_table")
    @classmethod
    def _one_geometry(
        cls, table: GeometryTable | None, info: ValidationInfo
    ) -> GeometryTable | None:
        if table is not None and info.data.get("geometry_factor") is not None:
            raise ValueError("a constant geometry_factor or a geometry_table, not both")
        return table

    @field_validator("growth_law")
    @classmethod
    def _constants_somewhere(cls, law: GrowthLaw | None, info: ValidationInfo) -> GrowthLaw | None:
        if law is None or law.learn or law.paris_c is not None:
            return law
        if info.data.get("material") is None and law.law != "nasgro":
            raise ValueError("both paris_c and paris_m, learn: true, or a material's constants")
        return law

    @field_validator("critical_crack_m")
    @classmethod
    def _above_initial(cls, critical: float | None, info: ValidationInfo) -> float | None:
        initial = info.data.get("initial_crack_m")
        if critical is not None and initial is not None and critical <= initial:
            raise ValueError(f"must exceed initial_crack_m ({initial:g} m), got {critical:g} m")
        return critical

    @field_validator("pod_a90_m")
    @classmethod
    def _above_a50(cls, a90: float | None, info: ValidationInfo) -> float | None:
        if "pod_a50_m" not in info.data:  # pod_a50_m itself was refused
            return a90
        a50 = info.data["pod_a50_m"]
        if a50 is not None and a90 is None:
            raise ValueError("pod_a50_m and pod_a90_m come together: pod_a90_m is missing")
        if a50 is None and a90 is not None:
            raise ValueError("pod_a50_m and pod_a90_m come together: pod_a50_m is missing")
        if a90 is not None and a50 is not None and a90 <= a50:
            raise ValueError(f"must exceed pod_a50_m ({a50:g} m), got {a90:g} m")
        return a90


class CrackCaseBetaOut(BaseModel):
    """beta(a) of the location's crack case as every march reads it (linear between the
    points, held outside), within max_relative_error of the closed form; where the case's
    validity range ends and why, a warning where the crack leaves it before a_crit; and the
    residual strength at each point (MPa) where a limit stress is given."""

    model_config = ex.examples(
        {
            "crack_length_m": [0.002, 0.03, 0.0683],
            "beta": [1.0001, 1.0252, 1.1416],
            "max_relative_error": 0.00093,
            "validity_limit_m": 0.105,
            "validity_reason": "2a/W = 0.7 (feddersen)",
            "warning": None,
            "residual_strength_mpa": [340.4, 253.0, 150.0],
        }
    )

    crack_length_m: list[float]
    beta: list[float]
    max_relative_error: float
    validity_limit_m: float
    validity_reason: str
    warning: str | None
    residual_strength_mpa: list[float] | None


class CriticalCrackOut(BaseModel):
    """a_crit from the limit stress, the criterion that sets it (fracture, net_section_yield,
    or extent: the crack reaches the end of its case first), each criterion's own crack, the
    toughness used and its kind (K_c, K_IC, given), and the residual strength at the initial
    crack with the criterion that sets it there and its margin over the limit stress (0.2: 20 %
    above)."""

    model_config = ex.examples(
        {
            "crack_length_m": 0.0683,
            "criterion": "fracture",
            "fracture_crack_m": 0.0683,
            "yield_crack_m": 0.0848,
            "toughness_mpa_sqrt_m": 80.0,
            "toughness_kind": "given",
            "yield_strength_mpa": 345.0,
            "residual_strength_at_initial_mpa": 340.4,
            "criterion_at_initial": "net_section_yield",
            "margin_at_initial": 1.269,
            "warning": None,
        }
    )

    crack_length_m: float
    criterion: str
    fracture_crack_m: float | None
    yield_crack_m: float | None
    toughness_mpa_sqrt_m: float
    toughness_kind: str
    yield_strength_mpa: float | None
    residual_strength_at_initial_mpa: float
    criterion_at_initial: str
    margin_at_initial: float
    warning: str | None


class LocationOut(LocationIn):
    """A catalogue entry as stored, with what its crack case computes (null without one)."""

    model_config = ConfigDict(
        json_schema_extra={"examples": [LOCATION_OUT]},
        from_attributes=True,
        extra="ignore",
        strict=False,
    )

    name: str
    created_at: datetime
    updated_at: datetime
    crack_case_beta: CrackCaseBetaOut | None = None
    critical_crack: CriticalCrackOut | None = None
    crack_case_error: str | None = Field(
        default=None,
        description="Why the stored crack case cannot be computed under today's settings.",
    )


class CarriedIn(BaseModel):
    """An aircraft's subset of the catalogue; null or empty: every location (the default)."""

    model_config = ex.examples(
        {"locations": ["default", "wing-splice"]}, {"locations": None}, extra="forbid"
    )

    locations: list[Annotated[str, Field(pattern=LOCATION_NAME)]] | None = Field(
        default=None, max_length=1000
    )


class CarriedOut(BaseModel):
    """The locations an aircraft carries, by name."""

    model_config = ex.examples({"tail": "N100", "locations": ["default", "wing-splice"]})

    tail: str
    locations: list[str]
