"""Request and response shapes of the API (never ORM classes)."""

from __future__ import annotations

from datetime import date, datetime
from typing import Annotated, Any, Literal

from fastapi import Path, Query
from pydantic import BaseModel, Field, field_validator

from app import schema_examples as ex
from app.schemas_ops import AssessmentOut, GateOut

# Uploads strip whitespace around tails, so a path tail may not carry any either.
TailPath = Annotated[
    str,
    Path(
        min_length=1,
        max_length=64,
        pattern=r"^\S(.*\S)?$",
        description="Aircraft tail number (no leading or trailing whitespace).",
    ),
]
AsOfQuery = Annotated[
    date | None,
    Query(
        description="Today for this answer (ISO date, UTC): the horizon counts from it, inspect-by "
        "dates before it are overdue.  Default: FLEETPINN_AS_OF, else the real date."
    ),
]
JobStatus = Literal["queued", "running", "succeeded", "failed", "cancelled"]


class HealthOut(BaseModel):
    model_config = ex.examples(ex.HEALTH)

    status: Literal["ok"] = "ok"


class ReadyOut(BaseModel):
    model_config = ex.examples(ex.READY)

    status: Literal["ready", "unavailable"]
    database: bool
    model_version: int | None = Field(description="The active model version; null when none.")


class AircraftIn(BaseModel):
    model_config = ex.examples(ex.AIRCRAFT_IN, extra="forbid")

    initial_crack_m: float | None = Field(
        default=None, gt=0, description="Known initial crack; null: the model's Paris-law a0."
    )


class AircraftOut(BaseModel):
    model_config = ex.examples(ex.AIRCRAFT_OUT)

    tail: str
    initial_crack_m: float | None
    created_at: datetime
    flight_count: int
    last_flown_at: datetime | None
    inspection_count: int


class AircraftPage(BaseModel):
    model_config = ex.examples(ex.AIRCRAFT_PAGE)

    items: list[AircraftOut]
    total: int
    limit: int
    offset: int


class FlightIn(BaseModel):
    """One flight; naive times are UTC."""

    model_config = ex.examples(ex.FLIGHT_IN, extra="forbid")

    flight_id: Annotated[str, Field(min_length=1, max_length=128)]
    flown_at: datetime
    stress_range_mpa: float
    mission: Annotated[str, Field(max_length=64)] | None = None


class IngestOut(BaseModel):
    model_config = ex.examples(ex.INGEST_OUT)

    inserted: int
    duplicates: int
    aircraft_created: int


class InspectionIn(BaseModel):
    """One inspection; naive times are UTC.  A crack measurement (detected, the default, with
    crack_length_m), or nothing found (detected false, with detection_threshold_m or the PoD
    curve pod_a50_m < pod_a90_m, and no crack_length_m); optionally a repair after it
    (repaired true with crack_after_repair_m).  The combinations are checked with the file
    contract's rules (model.record_validation.validate_inspections): 422 naming the field."""

    model_config = ex.examples(
        ex.INSPECTION_IN, ex.INSPECTION_NOT_FOUND_IN, ex.INSPECTION_REPAIR_IN, extra="forbid"
    )

    inspection_id: Annotated[str, Field(min_length=1, max_length=128)]
    inspected_at: datetime
    crack_length_m: float | None = Field(default=None, description="Required iff detected.")
    detected: bool = True
    detection_threshold_m: float | None = Field(
        default=None, description="Non-detection: a hard detection threshold (m)."
    )
    pod_a50_m: float | None = Field(
        default=None, description="Non-detection: crack detected with probability 0.5 (m)."
    )
    pod_a90_m: float | None = Field(
        default=None, description="Non-detection: crack detected with probability 0.9 (m)."
    )
    repaired: bool = False
    crack_after_repair_m: float | None = Field(
        default=None, description="Required iff repaired: the crack the tail restarts from (m)."
    )


class InspectionOut(BaseModel):
    model_config = ex.examples(ex.INSPECTION_OUT)

    inspection_id: str
    inspected_at: datetime
    crack_length_m: float | None
    detected: bool
    detection_threshold_m: float | None
    pod_a50_m: float | None
    pod_a90_m: float | None
    repaired: bool
    crack_after_repair_m: float | None
    forecast_crack_m: float | None = Field(
        description="The tail's forecast crack at the inspection when it was stored (null: none)."
    )
    forecast_z: float | None = Field(description="Finding against forecast (AssessmentOut).")
    flagged: bool = Field(description="The finding disagreed strongly with the forecast.")
    recorded_by: str | None = Field(
        description="The key that stored or last corrected it (null: before the audit log)."
    )


class InspectionIngestOut(IngestOut):
    model_config = ex.examples(ex.INSPECTION_INGEST_OUT)

    assessments: list[AssessmentOut] = Field(
        description="Each new inspection against its tail's forecast; flagged ones disagree "
        "strongly (they are stored all the same)."
    )


class RecordErrorOut(BaseModel):
    """Where an upload is wrong: 1-based data row (header excluded), column and reason."""

    model_config = ex.examples(ex.RECORD_ERROR)

    detail: str
    source: str
    row: int | None
    column: str | None
    reason: str


class RetrainIn(BaseModel):
    """Overrides of the service's training defaults for one retrain."""

    model_config = ex.examples(ex.RETRAIN_IN, extra="forbid")

    activate: bool = True
    kernel: Literal["physics", "mlp", "residual"] | None = None
    hidden: list[tuple[Annotated[int, Field(ge=1)], Literal["tanh", "elu", "linear"]]] | None = None
    optimizer: Literal["lbfgs", "rmsprop", "adam"] | None = None
    lbfgs_iterations: Annotated[int, Field(ge=1, le=10_000)] | None = None
    epochs: Annotated[int, Field(ge=1, le=100_000)] | None = None
    holdout_fraction: Annotated[float, Field(ge=0, lt=1)] | None = None
    seed: int | None = None


class JobAccepted(BaseModel):
    model_config = ex.examples(ex.JOB_ACCEPTED)

    job_id: str
    status: JobStatus


class JobOut(BaseModel):
    model_config = ex.examples(ex.JOB_OUT)

    job_id: str
    kind: str
    status: JobStatus
    progress: float
    stage: str | None = Field(description="What the job is doing now, in words.")
    params: dict[str, Any]
    model_version: int | None
    metrics: dict[str, Any] | None
    result: dict[str, Any] | None
    error: str | None
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    requested_by: str | None = Field(
        default=None, description="The key that queued the job (null: before the audit log)."
    )


class ModelVersionOut(BaseModel):
    model_config = ex.examples(ex.MODEL_VERSION_OUT)

    version: int
    status: Literal["candidate", "active", "retired"]
    created_at: datetime
    activated_at: datetime | None
    spec: dict[str, Any]
    training: dict[str, Any]
    metrics: dict[str, Any]
    gate: GateOut | None = Field(
        default=None,
        description="The promotion gate's verdict against the version active when it was "
        "trained (null: stored before the gate).",
    )
    job_id: str | None


class TrajectoryPoint(BaseModel):
    model_config = ex.examples(ex.TRAJECTORY_POINT)

    date: datetime
    flights: int = Field(description="Flights counted from the tail's first recorded flight.")
    crack_length_m: float = Field(description="Point projection (planned forecasts: the p50).")
    p05: float | None = Field(description="5 % quantile of the sampled crack (null: diverged).")
    p50: float | None
    p95: float | None


class CrackBand(BaseModel):
    model_config = ex.examples(ex.CRACK_BAND)

    p05: float | None
    p50: float | None
    p95: float | None


class CrackAt(BaseModel):
    """The projected crack on one day: the point value and the sampled quantiles."""

    model_config = ex.examples(ex.CRACK_AT)

    date: datetime
    flights: int = Field(description="Flights counted from the tail's first recorded flight.")
    crack_length_m: float | None = Field(
        description="Point projection; null: not finite (the march ran far past a_crit)."
    )
    p05: float | None
    p50: float | None
    p95: float | None


class FlightsQuantiles(BaseModel):
    """Quantiles of the flights after the origin until a_crit; null: not within the horizon."""

    model_config = ex.examples(ex.FLIGHTS_QUANTILES)

    p05: int | None
    p50: int | None
    p95: int | None


class DateQuantiles(BaseModel):
    """Dates of FlightsQuantiles at the forecast's rate; null: not within the horizon."""

    model_config = ex.examples(ex.DATE_QUANTILES)

    p05: datetime | None
    p50: datetime | None
    p95: datetime | None


class MissionShareIn(BaseModel):
    model_config = ex.examples(ex.MISSION_SHARE_IN, extra="forbid")

    stress_range_mpa: float = Field(gt=0, le=10_000)
    share: float = Field(ge=0, description="Relative weight of the mission (normalised).")


class PlannedUtilizationIn(BaseModel):
    """Future usage as planned: flights per day and a mission mix drawn i.i.d. per flight."""

    model_config = ex.examples(ex.PLANNED_UTILIZATION_IN, extra="forbid")

    flights_per_day: float = Field(gt=0, le=100)
    missions: list[MissionShareIn] = Field(min_length=1, max_length=100)

    @field_validator("missions")
    @classmethod
    def _some_share(cls, missions: list[MissionShareIn]) -> list[MissionShareIn]:
        if not sum(m.share for m in missions) > 0:
            raise ValueError("missions: at least one share must be > 0")
        return missions


class ForecastIn(BaseModel):
    model_config = ex.examples(ex.FORECAST_IN, extra="forbid")

    horizon_days: int = Field(default=365, ge=1, le=36_500)
    planned: PlannedUtilizationIn | None = Field(
        default=None, description="Planned utilization; null: resample the tail's recent flights."
    )


class GrowthOut(BaseModel):
    """The tail's own growth rate relative to the fleet model's (individual aircraft tracking)."""

    model_config = ex.examples(ex.GROWTH_OUT)

    factor_p05: float = Field(description="5 % quantile of the tail's growth-rate factor.")
    factor_p50: float = Field(description="Median factor: 1 grows like the fleet model.")
    factor_p95: float = Field(description="95 % quantile of the factor.")
    fleet_growth_sd: float = Field(
        description="sd of ln factor across the fleet (the prior), learned by the retrain."
    )
    sizing_relative_sd: float = Field(description="Relative sizing error of an inspection.")
    inspection_ids: list[str] = Field(
        description="The tail's inspections this forecast conditions on (measurements, "
        "non-detections, repairs)."
    )


class ForecastOut(BaseModel):
    model_config = ex.examples(ex.FORECAST_OUT)

    tail: str
    model_version: int
    origin: datetime = Field(
        description="Where the projection starts: the last recorded flight, or a repair "
        "dated after it."
    )
    last_flown_at: datetime = Field(description="Time of the tail's last recorded flight.")
    as_of: datetime = Field(
        description="Today (00:00 UTC), or the pinned as-of date: the horizon counts from it."
    )
    flights_flown: int
    crack_length_m: float = Field(
        description="Estimated crack at the origin (after the last flight)."
    )
    crack_length_band: CrackBand = Field(description="Sampled crack at the origin.")
    crack_as_of: CrackAt = Field(description="Projected crack on the as-of date.")
    crack_at_horizon: CrackAt = Field(
        description="Projected crack at the horizon's end, horizon_days after the as-of date."
    )
    critical_crack_m: float
    flights_per_day: float = Field(description="Projected utilization (recent or planned).")
    horizon_days: int
    samples: int = Field(description="Samples of (model weights, future usage) drawn.")
    model_uncertainty: bool = Field(
        description="Whether the model version has a weight posterior (else usage only)."
    )
    planned: bool = Field(description="Whether a planned utilization drove the projection.")
    trajectory: list[TrajectoryPoint] = Field(
        description="One point a day from the origin through the horizon's end."
    )
    flights_to_critical: int | None = Field(
        description="Flights after the origin until the crack reaches critical_crack_m (point "
        "projection, searched up to the extrapolation cap; planned: the p50 within the horizon)."
    )
    critical_date: datetime | None
    prob_critical: float = Field(
        description="P(crack reaches critical_crack_m by the horizon's end)."
    )
    flights_to_critical_quantiles: FlightsQuantiles
    critical_date_quantiles: DateQuantiles
    inspect_by: datetime | None = Field(
        description="Inspect by origin + half the p05 time to critical (MIL-STD-1530C "
        "practice); null when that lies beyond the horizon."
    )
    overdue: bool = Field(description="inspect_by lies before the as-of date.")
    growth: GrowthOut | None = Field(
        default=None,
        description="The tail's growth posterior from its own inspections; null for a model "
        "version trained before individual aircraft tracking.",
    )


class LastInspectionOut(BaseModel):
    model_config = ex.examples(ex.LAST_INSPECTION)

    inspection_id: str
    inspected_at: datetime
    detected: bool
    crack_length_m: float | None
    repaired: bool


class RankingItem(BaseModel):
    model_config = ex.examples(ex.RANKING_ITEM)

    rank: int
    tail: str
    crack_length_m: float
    crack_length_band: CrackBand
    critical_fraction: float = Field(description="crack_length_m / critical_crack_m.")
    crack_as_of_band: CrackBand = Field(description="Sampled crack on the as-of date.")
    crack_at_horizon_band: CrackBand = Field(description="Sampled crack at the horizon's end.")
    prob_critical: float
    inspect_by: datetime | None
    overdue: bool = Field(description="inspect_by lies before the as-of date.")
    flights_to_critical: int | None
    critical_date: datetime | None
    flights_to_critical_quantiles: FlightsQuantiles
    critical_date_quantiles: DateQuantiles
    last_inspection: LastInspectionOut | None
    flagged_inspection_ids: list[str] = Field(
        default_factory=list,
        description="The tail's inspections that disagreed strongly with its forecast: check them.",
    )
    flights_flown: int
    origin: datetime
    flights_per_day: float


class RankingOut(BaseModel):
    model_config = ex.examples(ex.RANKING_OUT)

    model_version: int
    critical_crack_m: float
    horizon_days: int
    as_of: datetime = Field(description="The as-of date (00:00 UTC) the horizon counts from.")
    by: Literal["risk", "crack", "due"]
    total: int
    items: list[RankingItem]


class ForecastBatchIn(BaseModel):
    model_config = ex.examples(ex.FORECAST_BATCH_IN, extra="forbid")

    model_version: int | None = Field(default=None, description="Default: the active version.")
