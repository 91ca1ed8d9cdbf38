"""Request and response shapes of the API (never ORM classes)."""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable
from datetime import datetime
from typing import Annotated, Any, Literal

from fastapi import Path, Query
from pydantic import AfterValidator, BaseModel, Field, Strict, field_validator
from pydantic.json_schema import JsonDict

from app import schema_examples as ex
from app.schema_rules import ABSENT, GIVEN, exactly_one_of, one_of_shapes, with_rules
from app.schema_types import Boolean, IsoDate, IsoDateTime, Number, WholeNumber
from app.schemas_locations import LOCATION_NAME
from app.schemas_ops import AssessmentOut, GateOut
from app.tables import DEFAULT_LOCATION
from model.posterior import ACTIVATIONS, OPTIMIZERS, kernel_names

# Uploads strip whitespace around tails (Python's str.strip), so a path tail may not carry any
# either.  The whitespace is spelled out, not `\S`: Python's re.ASCII (which schemathesis draws
# with), ECMA and Rust (pydantic's engine) each read `\s` differently, so "K\x85" was schema-valid
# to one and refused by the other; `[^\n]` is `.` as Python and Rust read it.
_WHITESPACE = (
    r"\u0009-\u000d\u001c-\u0020\u0085\u00a0\u1680\u2000-\u200a\u2028\u2029\u202f\u205f\u3000"
)
TAIL_PATTERN = rf"^[^{_WHITESPACE}](?:[^\n]*[^{_WHITESPACE}])?$"
TailPath = Annotated[
    str,
    Path(
        min_length=1,
        max_length=64,
        pattern=TAIL_PATTERN,
        description="Aircraft tail number (no leading or trailing whitespace).",
    ),
]
AsOfQuery = Annotated[
    IsoDate | None,
    Query(
        description="Today for this answer (ISO date, UTC): the horizon counts from it, inspect-by "
        "dates before it are overdue.  Default: FLEETPINN_AS_OF, else the real date.  It must lie "
        "between FLEETPINN_EARLIEST_RECORD_DATE and today + FLEETPINN_MAX_HORIZON_DAYS."
    ),
]
# Model versions are 32-bit integers in the database; a larger number cannot name one.
MAX_VERSION = 2**31 - 1
VersionPath = Annotated[int, Path(ge=1, le=MAX_VERSION, description="Model version number.")]
JobStatus = Literal["queued", "running", "succeeded", "failed", "cancelled"]


class HealthOut(BaseModel):
    model_config = ex.examples(ex.HEALTH)

    status: Literal["ok"] = "ok"


class ReadyOut(BaseModel):
    model_config = ex.examples(ex.READY)

    status: Literal["ready", "unavailable"]
    database: bool
    model_version: int | None = Field(
        description="The default location's active model version; null when none (a fleet of "
        "its own locations has its versions in model_versions)."
    )
    model_versions: dict[str, int] = Field(
        default_factory=dict,
        description="Every location's active model version, by location name; {} when none.",
    )


class AircraftIn(BaseModel):
    model_config = ex.examples(ex.AIRCRAFT_IN, extra="forbid", allow_inf_nan=False)

    initial_crack_m: Number | None = Field(
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


_ABOVE_ZERO: JsonDict = {"exclusiveMinimum": 0}
_BELOW_ONE: JsonDict = {"exclusiveMaximum": 1}


class CycleIn(BaseModel):
    """One cycle of a flight: stress_range_mpa and load_ratio (R = S_min / S_max < 1), or
    max_stress_mpa and min_stress_mpa; count 1 by default (0.5: a half cycle)."""

    # The pairs and bounds are checked where the flight is named (model.cycle_counting.from_cycles)
    # and stated here; min_stress_mpa below max_stress_mpa compares two values and is not.
    model_config = with_rules(
        ex.examples(ex.CYCLE_IN, ex.CYCLE_EXTREMES_IN, extra="forbid", allow_inf_nan=False),
        one_of_shapes(
            {
                "stress_range_mpa": GIVEN,
                "load_ratio": GIVEN,
                "max_stress_mpa": ABSENT,
                "min_stress_mpa": ABSENT,
            },
            {
                "stress_range_mpa": ABSENT,
                "load_ratio": ABSENT,
                "max_stress_mpa": GIVEN,
                "min_stress_mpa": GIVEN,
            },
        ),
    )

    stress_range_mpa: Number | None = Field(default=None, json_schema_extra=_ABOVE_ZERO)
    load_ratio: Number | None = Field(default=None, json_schema_extra=_BELOW_ONE)
    max_stress_mpa: Number | None = Field(default=None, json_schema_extra=_ABOVE_ZERO)
    min_stress_mpa: Number | None = None
    count: Number = Field(default=1.0, json_schema_extra=_ABOVE_ZERO)


_TENSILE_HISTORY: JsonDict = {"minItems": 2, "contains": {"type": "number", "exclusiveMinimum": 0}}


class FlightIn(BaseModel):
    """One flight; naive times are UTC.  Its loads in one of three forms: stress_range_mpa (one
    range), cycles (each with its range and load ratio, or its max and min), or
    stress_history_mpa (peaks and valleys, or a sampled series, in MPa: counted into cycles by
    rainflow at ingest).  Cycles and histories are stored as sent (model.cycle_counting), and
    the flight's stress_range_mpa is their damage-equivalent range under the configured law."""

    model_config = with_rules(
        ex.examples(
            ex.FLIGHT_IN,
            ex.FLIGHT_CYCLES_IN,
            ex.FLIGHT_HISTORY_IN,
            extra="forbid",
            allow_inf_nan=False,
        ),
        exactly_one_of("stress_range_mpa", "cycles", "stress_history_mpa"),
    )

    flight_id: Annotated[str, Field(min_length=1, max_length=128)]
    flown_at: IsoDateTime
    stress_range_mpa: Number | None = None
    # the fewest cycles and points are stated here and checked where the flight is named
    # (app.services.records.spectra)
    cycles: (
        Annotated[list[CycleIn], Field(max_length=10_000, json_schema_extra={"minItems": 1})] | None
    ) = None
    # a history holds a cycle that opens the crack: a tensile point (stated) and two points
    # apart (not statable: a history of equal points is a 422 naming it)
    stress_history_mpa: (
        Annotated[list[Number], Field(max_length=100_000, json_schema_extra=_TENSILE_HISTORY)]
        | None
    ) = None
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

    model_config = with_rules(
        ex.examples(
            ex.INSPECTION_IN,
            ex.INSPECTION_NOT_FOUND_IN,
            ex.INSPECTION_REPAIR_IN,
            extra="forbid",
            allow_inf_nan=False,
        ),
        # pod_a90_m > pod_a50_m compares two values: said in the docstring, not the schema
        one_of_shapes(
            {
                "detected": True,
                "crack_length_m": GIVEN,
                "detection_threshold_m": ABSENT,
                "pod_a50_m": ABSENT,
                "pod_a90_m": ABSENT,
            },
            {
                "detected": False,
                "crack_length_m": ABSENT,
                "detection_threshold_m": GIVEN,
                "pod_a50_m": ABSENT,
                "pod_a90_m": ABSENT,
            },
            {
                "detected": False,
                "crack_length_m": ABSENT,
                "detection_threshold_m": ABSENT,
                "pod_a50_m": GIVEN,
                "pod_a90_m": GIVEN,
            },
        ),
        one_of_shapes(
            {"repaired": False, "crack_after_repair_m": ABSENT},
            {"repaired": True, "crack_after_repair_m": GIVEN},
        ),
    )

    inspection_id: Annotated[str, Field(min_length=1, max_length=128)]
    inspected_at: IsoDateTime
    crack_length_m: Number | None = Field(default=None, description="Required iff detected.")
    detected: Boolean = True
    detection_threshold_m: Number | None = Field(
        default=None, description="Non-detection: a hard detection threshold (m)."
    )
    pod_a50_m: Number | None = Field(
        default=None, description="Non-detection: crack detected with probability 0.5 (m)."
    )
    pod_a90_m: Number | None = Field(
        default=None, description="Non-detection: crack detected with probability 0.9 (m)."
    )
    repaired: Boolean = False
    crack_after_repair_m: Number | None = Field(
        default=None, description="Required iff repaired: the crack the tail restarts from (m)."
    )
    location: str | None = Field(
        default=None,
        max_length=64,
        # stated, not checked here: a name off the pattern names no entry (a 422 naming it)
        json_schema_extra={"pattern": LOCATION_NAME},
        description="The control point inspected (GET /locations); null: 'default'.",
    )


class InspectionOut(BaseModel):
    model_config = ex.examples(ex.INSPECTION_OUT, from_attributes=True)

    inspection_id: str
    inspected_at: datetime
    crack_length_m: float | None
    detected: bool
    detection_threshold_m: float | None
    pod_a50_m: float | None
    pod_a90_m: float | None
    repaired: bool
    crack_after_repair_m: float | None
    location: str = Field(default=DEFAULT_LOCATION, description="The control point inspected.")
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


class InvalidOut(BaseModel):
    """422: nothing was stored.  A bad record names its source (file name or "body"), 1-based
    data row (header excluded), column and reason, detail being one line; a request that does not
    fit its schema carries FastAPI's list of issues as detail, and row and column of the first
    bad body row where there is one."""

    model_config = ex.examples(ex.RECORD_ERROR, ex.INVALID_REQUEST)

    detail: str | list[dict[str, Any]]
    source: str | None = None
    row: int | None = None
    column: str | int | None = None
    reason: str | None = None


class ErrorOut(BaseModel):
    """Why a request was refused (404, 409, 413, 503)."""

    model_config = ex.examples(ex.ERROR)

    detail: str


# Retrain budget: training memory grows with the units times the flights, the posterior's
# covariance with the weights squared (thesis Table 4.4's largest MLP: 4 layers, 40 units,
# 1,211 weights).
MAX_HIDDEN_LAYERS = 4
MAX_HIDDEN_UNITS = 64
MAX_NETWORK_WEIGHTS = 2000
_NETWORK_INPUTS = 2  # (stress range, crack length)


def _one_of(what: str, names: Callable[[], Iterable[str]]) -> Callable[[str], str]:
    """A check that a string names an entry of one of model/'s registries, read when
    validating (a kernel registered after import counts)."""

    def check(value: str) -> str:
        allowed = tuple(names())
        if value not in allowed:
            raise ValueError(f"{what} must be one of {allowed}, got {value!r}")
        return value

    return check


def _enum_of(names: Callable[[], Iterable[str]]) -> Callable[[dict[str, Any]], None]:
    """The registry's names as the schema's enum (read when the schema is built)."""

    def enum(schema: dict[str, Any]) -> None:
        schema["enum"] = list(names())

    return enum


def _activations() -> Iterable[str]:
    return ACTIVATIONS


def _optimizers() -> Iterable[str]:
    return OPTIMIZERS


# Kernels (model.cells.KERNELS), activations (model.nets.ACTIVATIONS), optimizers
# (model.train.OPTIMIZERS): the registries the model spec and the settings read.
KernelName = Annotated[
    str,
    AfterValidator(_one_of("kernel", kernel_names)),
    Field(json_schema_extra=_enum_of(kernel_names)),
]
ActivationName = Annotated[
    str,
    AfterValidator(_one_of("activation", _activations)),
    Field(json_schema_extra=_enum_of(_activations)),
]
OptimizerName = Annotated[
    str,
    AfterValidator(_one_of("optimizer", _optimizers)),
    Field(json_schema_extra=_enum_of(_optimizers)),
]


class RetrainIn(BaseModel):
    """Overrides of the service's training defaults for one retrain."""

    model_config = ex.examples(ex.RETRAIN_IN, extra="forbid", allow_inf_nan=False)

    activate: Boolean = True
    kernel: KernelName | None = None
    hidden: (
        list[
            tuple[
                Annotated[int, Strict(), Field(ge=1, le=MAX_HIDDEN_UNITS), WholeNumber],
                ActivationName,
            ]
        ]
        | None
    ) = Field(
        default=None,
        min_length=1,
        max_length=MAX_HIDDEN_LAYERS,
        description=f"Hidden layers (units, activation): at most {MAX_HIDDEN_LAYERS} layers of "
        f"at most {MAX_HIDDEN_UNITS} units, {MAX_NETWORK_WEIGHTS} weights in all (the "
        "posterior's covariance is weights x weights).",
    )
    optimizer: OptimizerName | None = None
    lbfgs_iterations: Annotated[int, Strict(), Field(ge=1, le=10_000), WholeNumber] | None = None
    epochs: Annotated[int, Strict(), Field(ge=1, le=100_000), WholeNumber] | None = None
    holdout_fraction: Annotated[Number, Field(ge=0, lt=1)] | None = None
    seed: Annotated[int, Strict(), Field(ge=0, le=2**32 - 1), WholeNumber] | None = None

    @field_validator("hidden")
    @classmethod
    def _network_size(cls, hidden: list[tuple[int, str]] | None) -> list[tuple[int, str]] | None:
        if hidden is not None:
            sizes = [_NETWORK_INPUTS, *(units for units, _ in hidden), 1]
            weights = sum((a + 1) * b for a, b in itertools.pairwise(sizes))
            if weights > MAX_NETWORK_WEIGHTS:
                raise ValueError(
                    f"the network would have {weights} weights, at most {MAX_NETWORK_WEIGHTS}"
                )
        return hidden


class JobAccepted(BaseModel):
    model_config = ex.examples(ex.JOB_ACCEPTED)

    job_id: str
    status: JobStatus
    jobs: dict[str, str] | None = Field(
        default=None,
        description="A retrain's job per location (location name: job id), one per location "
        "some aircraft with flights carries; job_id is the default location's where it has "
        "one, else the first's.  Cancelling any of them cancels all.",
    )
    already_queued: list[str] = Field(
        default=[],
        description="Jobs of `jobs` an earlier request queued and that have not started: a "
        "location has at most one queued retrain, so this request's options were not applied "
        "to it (cancel it, POST /jobs/{job_id}/cancel, to queue others).",
    )


class JobOut(BaseModel):
    model_config = ex.examples(ex.JOB_OUT, from_attributes=True)

    job_id: str
    kind: str
    status: JobStatus
    progress: float
    stage: str | None = Field(description="What the job is doing now, in words.")
    params: dict[str, Any]
    model_version: int | None
    outcome: Literal["activated", "candidate", "refused", "superseded"] | None = Field(
        default=None,
        description="A finished retrain's end: activated; candidate (stored, not activated, as "
        "asked); refused (the promotion gate kept the active version: outcome_reason and "
        "metrics.gate say why); superseded (another version was activated meanwhile).  Null: "
        "another kind of job, or not finished.",
    )
    outcome_reason: str | None = Field(default=None, description="Why, in words.")
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
    model_config = ex.examples(ex.MODEL_VERSION_OUT, from_attributes=True)

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
    location: str | None = Field(
        default=None,
        description="The location the version was trained for and serves (one active "
        "version per location).",
    )
