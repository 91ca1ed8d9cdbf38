"""Request and response shapes of forecasts, the fleet ranking and batch forecasts (never ORM
classes); app.schemas holds the records', models' and jobs' shapes."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Literal

from pydantic import BaseModel, Field, Strict, field_validator

from app import schema_examples as ex
from app.schema_types import Boolean, Integer, Number, WholeNumber
from app.schemas import MAX_VERSION
from app.schemas_residual import LineStrengthOut, ResidualStrengthOut

_PAST_CRITICAL = (
    "The p50 crack on the as-of date has reached critical_crack_m: the tail is past critical. "
    "Crack lengths at or past a_crit are reported as null (a march holds them at a bound that "
    "measures nothing)."
)
_PAST_CRITICAL_SINCE = "The date the p50 crack reached critical_crack_m (null: not past critical)."
_PAST_NULL = " Null at or past critical_crack_m (see past_critical), or not finite."


class TrajectoryPoint(BaseModel):
    model_config = ex.examples(ex.TRAJECTORY_POINT, from_attributes=True)

    date: datetime
    flights: int = Field(description="Flights counted from the tail's first recorded flight.")
    crack_length_m: float | None = Field(
        description="Point projection (planned forecasts: the p50); the trajectory ends at the "
        "first flight at or past critical_crack_m; null: not finite."
    )
    p05: float | None = Field(description="5 % quantile of the sampled crack." + _PAST_NULL)
    p50: float | None
    p95: float | None


class CrackBand(BaseModel):
    """Quantiles of a sampled crack; each is null at or past critical_crack_m (see
    past_critical), or where not finite."""

    model_config = ex.examples(ex.CRACK_BAND, from_attributes=True)

    p05: float | None
    p50: float | None
    p95: float | None


class CrackAt(BaseModel):
    """The projected crack on one day: the point value and the sampled quantiles."""

    model_config = ex.examples(ex.CRACK_AT, from_attributes=True)

    date: datetime
    flights: int = Field(description="Flights counted from the tail's first recorded flight.")
    crack_length_m: float | None = Field(description="Point projection." + _PAST_NULL)
    p05: float | None
    p50: float | None
    p95: float | None


class FlightsQuantiles(BaseModel):
    """Quantiles of the flights after the origin until a_crit; null: not within the horizon."""

    model_config = ex.examples(ex.FLIGHTS_QUANTILES, from_attributes=True)

    p05: int | None
    p50: int | None
    p95: int | None


class DateQuantiles(BaseModel):
    """Dates of FlightsQuantiles at the forecast's rate; null: not within the horizon."""

    model_config = ex.examples(ex.DATE_QUANTILES, from_attributes=True)

    p05: datetime | None
    p50: datetime | None
    p95: datetime | None


# Shares are relative weights: bounded so that their sum stays finite and normalisable.
MAX_SHARE = 1e6


class MissionShareIn(BaseModel):
    model_config = ex.examples(ex.MISSION_SHARE_IN, extra="forbid", allow_inf_nan=False)

    stress_range_mpa: Number = Field(gt=0, le=10_000)
    share: Number = Field(
        ge=0,
        le=MAX_SHARE,
        description="Relative weight of the mission (normalised over the missions).",
    )


class PlannedUtilizationIn(BaseModel):
    """Future usage as planned: flights per day and a mission mix drawn i.i.d. per flight."""

    model_config = ex.examples(ex.PLANNED_UTILIZATION_IN, extra="forbid", allow_inf_nan=False)

    flights_per_day: Number = Field(gt=0, le=100)
    missions: list[MissionShareIn] = Field(
        min_length=1,
        max_length=100,
        # stated in the schema: some share is > 0 (_some_share)
        json_schema_extra={"contains": {"properties": {"share": {"exclusiveMinimum": 0}}}},
    )

    @field_validator("missions")
    @classmethod
    def _some_share(cls, missions: list[MissionShareIn]) -> list[MissionShareIn]:
        if not sum(m.share for m in missions) > 0:
            raise ValueError("missions: at least one share must be > 0")
        return missions


class ForecastIn(BaseModel):
    model_config = ex.examples(ex.FORECAST_IN, extra="forbid", allow_inf_nan=False)

    horizon_days: Integer = Field(
        default=365,
        ge=1,
        description="Days after the as-of date; at most FLEETPINN_MAX_HORIZON_DAYS (3650): "
        "more is refused with a 422.",
    )
    planned: PlannedUtilizationIn | None = Field(
        default=None, description="Planned utilization; null: resample the tail's recent flights."
    )


class DataAgeOut(BaseModel):
    """How old the tail's data are on the as-of date: a forecast of a stale tail extrapolates
    loads and cracks nobody has seen for that long."""

    model_config = ex.examples(ex.DATA_AGE_OUT, from_attributes=True)

    last_flown_at: datetime = Field(description="The tail's last recorded flight.")
    last_inspected_at: datetime | None = Field(description="Its latest inspection (null: none).")
    days_since_last_flight: int = Field(description="Whole days to the as-of date (0: up to date).")
    days_since_last_inspection: int | None = Field(description="Null: never inspected.")
    stale: bool = Field(
        description="days_since_last_flight exceeds stale_after_days (setting "
        "FLEETPINN_STALE_AFTER_DAYS)."
    )


class GrowthOut(BaseModel):
    """The tail's own growth rate relative to the fleet model's (individual aircraft tracking)."""

    model_config = ex.examples(ex.GROWTH_OUT, from_attributes=True)

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


class LocationSummaryOut(BaseModel):
    """One location's forecast of a tail, in the fields a decision reads."""

    model_config = ex.examples(
        {
            "location": "wing-splice",
            "model_version": 4,
            "crack_as_of_m": 0.0121,
            "critical_crack_m": 0.04,
            "prob_critical": 0.02,
            "inspect_by": "2027-03-01T00:00:00Z",
            "overdue": False,
            "past_critical": False,
        },
        from_attributes=True,
    )

    location: str
    model_version: int
    crack_as_of_m: float | None = Field(description="p50 on the as-of date." + _PAST_NULL)
    critical_crack_m: float
    prob_critical: float
    inspect_by: datetime | None
    overdue: bool
    past_critical: bool
    residual_strength: LineStrengthOut | None = Field(
        default=None,
        description="At crack_as_of_m's p50, where the location gives limit_stress_mpa "
        "(absent otherwise).",
    )


class LocationNoteOut(BaseModel):
    """A carried location the aircraft's answer leaves out (no active version) or forecasts
    from the fleet alone (never inspected on this tail), and why."""

    model_config = ex.examples(
        {
            "location": "keel",
            "reason": "no active model version: no retrain has trained this "
            "location yet (POST /models/retrain trains every location an aircraft with flights "
            "carries)",
        },
        from_attributes=True,
    )

    location: str
    reason: str


class ForecastOut(BaseModel):
    model_config = ex.examples(ex.FORECAST_OUT, from_attributes=True)

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
    crack_length_m: float | None = Field(
        description="Estimated crack at the origin (after the last flight)." + _PAST_NULL
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
        "practice), or by the half-life rule (inspect_rule); null when that lies beyond the "
        "horizon."
    )
    inspect_rule: str = Field(
        description="The rule inspect_by follows (FLEETPINN_INSPECT_BY_RULE): half the p05 time "
        "to critical, or the damage-tolerance half-life rule (midway through the p05 crack's "
        "life from detectable to critical)."
    )
    overdue: bool = Field(description="inspect_by lies before the as-of date.")
    past_critical: bool = Field(description=_PAST_CRITICAL)
    past_critical_since: datetime | None = Field(description=_PAST_CRITICAL_SINCE)
    data_age: DataAgeOut
    stale_after_days: int = Field(description="Data older than this many days are stale.")
    growth: GrowthOut | None = Field(
        default=None,
        description="The tail's growth posterior from its own inspections; null for a model "
        "version trained before individual aircraft tracking.",
    )
    # Only where the fleet has locations with models of their own (absent otherwise: a
    # one-location fleet answers as before locations).
    governing_location: str | None = Field(
        default=None,
        description="GET /aircraft/{tail}/forecast of a fleet with several locations (or of a "
        "tail that does not carry the default one): the location with the highest "
        "P(critical), then the earliest inspect-by.  The body's other fields are the forecast "
        "of `location`.",
    )
    location: str | None = Field(
        default=None,
        description="Beside governing_location: the location the body's fields are of (the "
        "default one where the tail carries it with an active version, as before locations; "
        "else the governing one).",
    )
    locations: list[LocationSummaryOut] | None = Field(
        default=None,
        description="Every location with an active version, governing first "
        "(/aircraft/{tail}/locations/{name}/forecast has each one in full).",
    )
    # Only where the tail carries such locations (absent otherwise, as before locations).
    unassessed_locations: list[str] | None = Field(
        default=None,
        description="GET/POST /aircraft/{tail}/forecast: the locations the tail carries that "
        "have no active model version yet (catalogued after the last retrain, or their "
        "retrain failed or is pending), by name.  Their risk is not in this answer, nor in "
        "governing_location and locations: a retrain (POST /models/retrain) gives them one.",
    )
    location_notes: list[LocationNoteOut] | None = Field(
        default=None,
        description="GET /aircraft/{tail}/forecast: each carried location without an active "
        "version, and (with several locations) each the tail was never inspected at, with the "
        "reason in words; absent where there are none.",
    )
    residual_strength: ResidualStrengthOut | None = Field(
        default=None,
        description="The residual strength at the crack on the as-of date (crack_as_of's p50 "
        "and p95) and its margin over the location's limit stress, from its crack case (or "
        "geometry table) and toughness; absent where the location gives no limit_stress_mpa, "
        "or has neither (a constant geometry factor, no toughness or material).",
    )
    # Only where as_of lies before the origin (absent otherwise).
    as_of_note: str | None = Field(
        default=None,
        description="as_of lies before the origin's date: the projection starts at the origin "
        "from every record up to it, flights after as_of included (no forecast as known on "
        "as_of is made); crack_as_of is the crack at the origin and the horizon counts from "
        "the origin.  Absent where as_of lies on or after the origin's date.",
    )


class LastInspectionOut(BaseModel):
    model_config = ex.examples(ex.LAST_INSPECTION, from_attributes=True)

    inspection_id: str
    inspected_at: datetime
    detected: bool
    crack_length_m: float | None
    repaired: bool


class RankingItem(BaseModel):
    model_config = ex.examples(ex.RANKING_ITEM, from_attributes=True)

    rank: int
    tail: str
    crack_length_m: float | None = Field(description="Crack after the last flight." + _PAST_NULL)
    crack_length_band: CrackBand
    critical_fraction: float | None = Field(
        description="crack_length_m / critical_crack_m (null where crack_length_m is)."
    )
    crack_as_of_band: CrackBand = Field(description="Sampled crack on the as-of date.")
    crack_at_horizon_band: CrackBand = Field(description="Sampled crack at the horizon's end.")
    prob_critical: float
    inspect_by: datetime | None
    overdue: bool = Field(description="inspect_by lies before the as-of date.")
    past_critical: bool = Field(description=_PAST_CRITICAL)
    past_critical_since: datetime | None = Field(description=_PAST_CRITICAL_SINCE)
    data_age: DataAgeOut
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
    # Only where several locations have models (absent otherwise: a one-location fleet ranks
    # as before locations).
    location: str | None = Field(
        default=None,
        description="A (tail, location) row's location; an aircraft's rows stay together, its "
        "governing one first.",
    )
    model_version: int | None = Field(default=None, description="The row's location's version.")
    critical_crack_m: float | None = Field(
        default=None, description="The row's location's critical crack."
    )
    residual_strength: LineStrengthOut | None = Field(
        default=None,
        description="At crack_as_of_band's p50, where the row's location gives "
        "limit_stress_mpa (absent otherwise), as the tail's forecast reports it.",
    )


class RankingOut(BaseModel):
    model_config = ex.examples(ex.RANKING_OUT, from_attributes=True)

    model_version: int = Field(
        description="The ranked version; with several locations, the default location's (or "
        "the first location's): each row names its own."
    )
    critical_crack_m: float = Field(
        description="The ranked version's a_crit; with several locations each row has its own "
        "location's (`critical_crack_m` on the row), which its crack bands are read against."
    )
    horizon_days: int
    as_of: datetime = Field(description="The as-of date (00:00 UTC) the horizon counts from.")
    by: Literal["risk", "crack", "due"]
    total: int
    stale_after_days: int = Field(description="Data older than this many days are stale.")
    items: list[RankingItem]


class ForecastBatchIn(BaseModel):
    model_config = ex.examples(ex.FORECAST_BATCH_IN, extra="forbid")

    model_version: Annotated[int, Strict(), Field(ge=1, le=MAX_VERSION), WholeNumber] | None = (
        Field(default=None, description="Default: the active version.")
    )
    refresh: Boolean = Field(
        default=False,
        description="Recompute every tail's forecast, not only those without a current one "
        "(after a change of the settings forecasts are computed under).",
    )
