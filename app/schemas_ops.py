"""Shapes of the routes that keep records and models trustworthy: record corrections, inspection
assessments against the forecast, the promotion gate, the audit log (never ORM classes)."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Field, field_validator

from app import schema_examples as ex
from app.schema_types import Boolean, IsoDateTime, Number, never_null


class FlightOut(BaseModel):
    model_config = ex.examples(ex.FLIGHT_OUT, from_attributes=True)

    flight_id: str
    flown_at: datetime
    stress_range_mpa: float
    mission: str | None
    recorded_by: str | None = Field(
        description="The key (or local command) that stored or last corrected the flight; null "
        "for flights stored before the audit log."
    )


def _not_null(value: Any) -> Any:
    """A field every stored record has: it may be changed or left out, not cleared."""
    if value is None:
        raise ValueError("may not be null: send a value, or leave the field out to keep it")
    return value


class FlightPatch(BaseModel):
    """The fields of a stored flight to change (its flight_id stays); the corrected flight is
    checked as a new one is."""

    model_config = ex.examples(ex.FLIGHT_PATCH, extra="forbid", allow_inf_nan=False)

    flown_at: IsoDateTime | None = Field(default=None, json_schema_extra=never_null)
    stress_range_mpa: Number | None = Field(default=None, json_schema_extra=never_null)
    mission: Annotated[str, Field(max_length=64)] | None = Field(
        default=None, description="null clears the mission."
    )

    @field_validator("flown_at", "stress_range_mpa")
    @classmethod
    def _kept(cls, value: Any) -> Any:
        return _not_null(value)


class InspectionPatch(BaseModel):
    """The fields of a stored inspection to change (its inspection_id stays); null clears a field
    (e.g. crack_length_m when it becomes a non-detection).  The corrected inspection is checked
    as a new one is, and compared with the forecast again."""

    model_config = ex.examples(ex.INSPECTION_PATCH, extra="forbid", allow_inf_nan=False)

    inspected_at: IsoDateTime | None = Field(default=None, json_schema_extra=never_null)
    crack_length_m: Number | None = None
    detected: Boolean | None = Field(default=None, json_schema_extra=never_null)
    detection_threshold_m: Number | None = None
    pod_a50_m: Number | None = None
    pod_a90_m: Number | None = None
    repaired: Boolean | None = Field(default=None, json_schema_extra=never_null)
    crack_after_repair_m: Number | None = None

    @field_validator("inspected_at", "detected", "repaired")
    @classmethod
    def _kept(cls, value: Any) -> Any:
        return _not_null(value)


class AssessmentOut(BaseModel):
    """A new inspection against its tail's forecast (docs/api.md, "Plausibility and flags")."""

    model_config = ex.examples(ex.ASSESSMENT_OUT)

    inspection_id: str
    forecast_crack_m: float | None = Field(
        description="The forecast crack at the inspection (null: no forecast, e.g. no active "
        "model or no flights)."
    )
    forecast_z: float | None = Field(
        description="Standard deviations between finding and forecast in log space (forecast "
        "spread and sizing error together); for a non-detection, how far the forecast lies "
        "above the detection limit."
    )
    flagged: bool = Field(description="|z| above FLEETPINN_INSPECTION_FLAG_Z (3): check it.")


class GateOut(BaseModel):
    """The promotion gate's verdict on a version, with each side's |% error| on the same
    inspections."""

    model_config = ex.examples(ex.GATE_OUT)

    passed: bool
    reason: str
    evaluated_on: Literal["validation", "training"]
    candidate: dict[str, Any]
    active_version: int | None = Field(description="The version compared with (null: none).")
    active: dict[str, Any] | None
    max_error_pct: float = Field(description="Bound of a first version's mean |% error|.")
    max_error_increase_pct: float
    max_error_increase_ratio: float
    culprits: list[dict[str, Any]] = Field(
        default_factory=list,
        description="A refusal's inspections (tail/inspection_id) the candidate predicts worst "
        "against the active version, most first, with both |% error|s.",
    )
    flagged: list[dict[str, Any]] = Field(
        default_factory=list,
        description="A refusal's flagged inspections (tail/inspection_id, z) the candidate "
        "trained on: what may have moved it.",
    )


class AuditEventOut(BaseModel):
    model_config = ex.examples(ex.AUDIT_EVENT_OUT)

    id: int
    at: datetime
    actor: str = Field(description="The key's name, or cli:<command> for a local command.")
    role: str
    action: str
    subject: str
    request_id: str | None
    detail: dict[str, Any] = Field(description="Counts, or the values before a change.")


class AuditPage(BaseModel):
    model_config = ex.examples(ex.AUDIT_PAGE)

    items: list[AuditEventOut]
    total: int
    limit: int
    offset: int
