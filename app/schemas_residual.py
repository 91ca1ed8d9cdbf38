"""The residual strength at a tail's crack now, as its forecast reports it
(app.services.forecasts.residual_now says what it is computed from)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from app import schema_examples as ex

# a Feddersen centre crack in a 0.3 m panel, K = 80 MPa sqrt(m), sigma_y = 345 MPa, limit 150 MPa
_AT_P50: ex.Example = {
    "crack_length_m": 0.02,
    "residual_strength_mpa": 299.0,
    "criterion": "net_section_yield",
    "margin": 0.993,
}
_AT_P95: ex.Example = {
    "crack_length_m": 0.026,
    "residual_strength_mpa": 274.7,
    "criterion": "fracture",
    "margin": 0.831,
}
_CRITERION = (
    "What sets the strength: fracture (K_c / (beta sqrt(pi a))), net_section_yield (sigma_y "
    "A_net / A_gross) or extent (the section severed, or the crack not finite: 0 MPa)."
)


class StrengthAtOut(BaseModel):
    """The residual strength at one quantile of the crack on the as-of date."""

    model_config = ex.examples(_AT_P50, _AT_P95, from_attributes=True)

    crack_length_m: float | None = Field(
        description="The crack it is computed at (crack_as_of's quantile). Null at or past "
        "critical_crack_m, or not finite."
    )
    residual_strength_mpa: float = Field(description="The stress the cracked section carries.")
    criterion: Literal["fracture", "net_section_yield", "extent"] = Field(description=_CRITERION)
    margin: float = Field(
        description="residual_strength_mpa / limit_stress_mpa - 1 (0.2: 20 % above the limit; "
        "< 0: the section no longer carries it)."
    )


class ResidualStrengthOut(BaseModel):
    """The residual strength at the crack now: p50, and p95 (the conservative value)."""

    model_config = ex.examples(
        {
            "p50": _AT_P50,
            "p95": _AT_P95,
            "limit_stress_mpa": 150.0,
            "toughness_mpa_sqrt_m": 80.0,
            "toughness_kind": "given",
            "yield_strength_mpa": 345.0,
        },
        from_attributes=True,
    )

    p50: StrengthAtOut
    p95: StrengthAtOut = Field(description="At the p95 crack: the conservative strength.")
    limit_stress_mpa: float = Field(description="The location's limit stress.")
    toughness_mpa_sqrt_m: float
    toughness_kind: Literal["K_c", "K_IC", "given"]
    yield_strength_mpa: float | None = Field(description="Null: net-section yield not checked.")


class LineStrengthOut(BaseModel):
    """The residual strength at a location's line's p50 crack (crack_as_of_m) and its margin
    over the location's limit stress; a line has one only where its location gives a limit
    stress."""

    model_config = ex.examples(
        {
            "residual_strength_mpa": 299.0,
            "criterion": "net_section_yield",
            "margin": 0.993,
            "limit_stress_mpa": 150.0,
        },
        from_attributes=True,
    )

    residual_strength_mpa: float = Field(
        description="The stress the cracked section carries at the p50 crack on the as-of date."
    )
    criterion: Literal["fracture", "net_section_yield", "extent"] = Field(description=_CRITERION)
    margin: float = Field(
        description="residual_strength_mpa / limit_stress_mpa - 1 (< 0: the section no longer "
        "carries the limit stress)."
    )
    limit_stress_mpa: float = Field(description="The location's limit stress.")
