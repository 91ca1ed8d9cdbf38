"""Service configuration: one Settings object read from FLEETPINN_* environment variables."""

from __future__ import annotations

from collections.abc import Callable
from datetime import UTC, date, datetime
from functools import lru_cache
from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, ValidationInfo, field_validator, model_validator

from app.settings_db import DatabaseSettings
from model.materials import law_for, user_table
from model.physics import ParisLaw
from model.posterior import (
    DEFAULT_RESTARTS,
    DEFAULT_SLOPE_SD,
    OPTIMIZERS,
    SizingError,
    kernel_names,
)

# How long an API process keeps an idle keep-alive connection open (uvicorn's default: 5 s).
# Longer than clients' pools keep theirs (httpx: 5 s): at equal times a client reused a
# connection just as the server closed it and got a reset (benchmarks/load.py's ReadErrors).
KEEP_ALIVE_SECONDS = 75

# Allowed values, read when validating: kernels may be registered after import (model.cells).
_CHOICES: dict[str, Callable[[], tuple[str, ...]]] = {
    "kernel": kernel_names,
    "optimizer": lambda: tuple(OPTIMIZERS),
}


class Settings(DatabaseSettings):
    """Everything the service reads from its environment (the database's URL from
    DatabaseSettings); invalid values fail at start-up."""

    # Apply migrations when the app starts (off when a deploy step runs `fleetpinn migrate`).
    migrate_on_start: bool = True
    # The in-process worker thread; switch it off when `fleetpinn worker` processes run the jobs.
    run_worker: bool = True
    worker_poll_seconds: Annotated[float, Field(gt=0)] = 0.5
    # Each API process makes the tails' forecasts before they are asked, in a thread below its
    # requests, after a version's activation and a tail's change (app.services.forecasts.answers_ahead).
    answers_ahead: bool = True
    # How much lower `fleetpinn worker` processes run than the API (os.nice increment, 0-19): a
    # retrain on the API's cores then takes the CPU that requests leave (benchmarks/load.py).
    worker_nice: Annotated[int, Field(ge=0, le=19)] = 10
    # A running job whose worker has not beaten for this long is claimed again (worker died).
    job_stale_seconds: Annotated[float, Field(gt=0)] = 300.0

    # Request limits (app.limits): refused with 413 (body) or 422 (rows) naming the setting;
    # page sizes are capped by each route's own limit parameter (422 above it).
    max_upload_bytes: Annotated[int, Field(ge=1024)] = 512 * 1024 * 1024
    max_body_bytes: Annotated[int, Field(ge=1024)] = 16 * 1024 * 1024
    max_batch_rows: Annotated[int, Field(ge=1)] = 50_000
    # Rows of one uploaded file (a CSV's lines, a Parquet file's footer), checked before it is
    # parsed: an upload's rows are held in memory while stored (~0.5 kB each at the peak,
    # docs/api.md), so a million keep an API process under its 2 GiB.
    max_upload_rows: Annotated[int, Field(ge=1)] = 1_000_000
    request_timeout_seconds: Annotated[float, Field(gt=0)] = 30.0
    # Queued jobs (retrains, batch forecasts) the API accepts at most; more are refused with
    # 429 (app.services.jobs.queue).  A retrain queues one job per inspected location.
    max_queued_jobs: Annotated[int, Field(ge=1)] = 20
    # Memory one request's sampling may hold (app.budget): tails are sampled in groups that fit
    # it, and one tail's future may hold at most this / (24 B x forecast_samples) flights per
    # draw (422 above).  With request_threads at once it bounds an API process (docs/api.md).
    max_sampling_bytes: Annotated[int, Field(ge=16 * 1024 * 1024)] = 256 * 1024 * 1024
    # Threads that run sync routes at once per API process (AnyIO's pool; its default is 40).
    # Past a few they only take turns at the GIL and the event loop waits behind them: under
    # benchmarks/load.py 32 clients saw seconds-long tails with 40, far less with a few.
    request_threads: Annotated[int, Field(ge=1, le=40)] = 4
    # A key found valid is trusted this long before it is read again (app.auth), so a revoked
    # key is refused within this many seconds by every process; 0: read on every request.
    key_cache_seconds: Annotated[float, Field(ge=0, le=60)] = 1.0

    # Paris-law constants (thesis defaults): SI units, stress in MPa, crack in m.
    paris_c: Annotated[float, Field(gt=0)] = 1.5e-11
    paris_m: Annotated[float, Field(gt=0)] = 3.8
    geometry_factor: Annotated[float, Field(gt=0)] = 1.0
    initial_crack_m: Annotated[float, Field(gt=0)] = 0.005
    critical_crack_m: Annotated[float, Field(gt=0)] = 0.05
    # Fit C and m to the inspections at each retrain (model.paris_calibration), starting from
    # paris_c and paris_m: for an alloy whose constants are not known.  The active version's
    # constants are in its metrics ("paris").
    learn_paris: bool = False
    # The growth law (model.growth_laws): "paris", "walker" (da/dN = C [dK / (1 - R)**(1 -
    # gamma)]**m; gamma is learned with C and m under learn_paris where flights carry cycles),
    # or "nasgro" (model.nasgro: its terms from a material whose row has them; not learned).
    growth_law: Literal["paris", "walker", "nasgro"] = "paris"
    walker_gamma: Annotated[float, Field(ge=0, le=1)] = 1.0
    # An alloy by name (e.g. "2024-T3"), of model/data/materials.csv or materials_file: its C,
    # m and gamma (and NASGRO terms, where its row has them) replace paris_c, paris_m and
    # walker_gamma; the geometry stays these settings'.
    material: str | None = None
    # A CSV of the shipped table's columns (model.materials_file, docs/api.md) whose rows add to
    # the shipped ones and replace a shipped row of the same name: the operator's own constants,
    # e.g. NASGRO terms from a licensed database.  Checked in full at start-up; it names the
    # alloys material and the catalogue's locations may take.
    materials_file: Path | None = None

    # Training defaults for retrain jobs (a request may override them).
    kernel: str = "physics"
    optimizer: str = "lbfgs"
    # Bounded as a request's overrides are (app.schemas.RetrainIn).
    lbfgs_iterations: Annotated[int, Field(ge=1, le=10_000)] = 60
    epochs: Annotated[int, Field(ge=1, le=100_000)] = 100
    holdout_fraction: Annotated[float, Field(ge=0, lt=1)] = 0.2
    seed: int = 0
    # Modes of the stored Laplace posterior mixture (model.uncertainty_fit): the fit's own plus
    # restarts - 1 refits; each refit costs about one more fit.
    posterior_restarts: Annotated[int, Field(ge=1, le=50)] = DEFAULT_RESTARTS

    # Individual aircraft tracking (model.tracking): inspection sizing error, sd of
    # ln(measured / true) = sqrt(relative**2 + (absolute / crack)**2); a retrain re-estimates the
    # relative part where tails have repeated measurements.
    sizing_relative_sd: Annotated[float, Field(gt=0, le=1)] = 0.05
    sizing_absolute_sd_m: Annotated[float, Field(ge=0, le=0.01)] = 0.0001
    # sd of ln growth rate across tails assumed while fewer than 5 tails are inspected (a retrain
    # learns it from 5 on); 0 keeps every tail at the fleet model's rate until then.
    growth_sd_prior: Annotated[float, Field(ge=0, le=1.5)] = 0.0
    # sd of the geometry factor's slope in ln a beyond the longest measured crack
    # (model.extrapolation): how far forecasts beyond the data may be off, which no inspection
    # below it can tell; 0 trusts the fitted trend there.
    extrapolation_slope_sd: Annotated[float, Field(ge=0, le=1)] = DEFAULT_SLOPE_SD

    # Forecasting: utilization (flights a day) is projected from this much recent data per tail,
    utilization_window_days: Annotated[int, Field(ge=1)] = 90
    # and future loads are resampled from this much (at least the utilization window): a
    # flight's damage goes as its range**m, a heavy tail, and 90 days of it ran short of the
    # next year's (benchmarks/extrapolation_service.py, flat fleet: uninspected [p05, p95]
    # held 80 % at a median p50 bias of -0.50 %; from 365 days 91 % and -0.38 %)
    load_window_days: Annotated[int, Field(ge=1)] = 365
    max_horizon_days: Annotated[int, Field(ge=1)] = 3650
    # Time to critical is extrapolated past the requested horizon up to this many years.
    critical_search_years: Annotated[float, Field(gt=0)] = 30.0
    # Probabilistic forecasts: samples of (posterior weights, future usage), their seed, and the
    # horizon whose risk a retrain or batch forecast precomputes for every tail.
    forecast_samples: Annotated[int, Field(ge=1, le=5000)] = 200
    forecast_seed: int = 0
    forecast_horizon_days: Annotated[int, Field(ge=1)] = 365
    # "Today" for forecasts, rankings and exports (ISO date, UTC); unset: the real date.  Pin it
    # for reproducible demos and tests: horizons count from it, inspect-by dates before it are
    # overdue.
    as_of: date | None = None
    # A tail whose last recorded flight lies more than this many days before the as-of date is
    # marked stale (pages, forecast, ranking, export): its forecast extrapolates old data.
    stale_after_days: Annotated[int, Field(ge=1)] = 60
    # Inspect-by: "half_remaining", half the p05 flights to critical from now; "half_life", the
    # damage-tolerance half-life rule: midway through the p05 crack's life from detectable
    # (detectable_crack_m, e.g. the inspection method's a90) to critical.  Stored risk follows
    # the rule it was sampled under until its next refill (`fleetpinn forecast-batch --refresh`).
    inspect_by_rule: Literal["half_remaining", "half_life"] = "half_remaining"
    detectable_crack_m: Annotated[float, Field(gt=0, le=1)] = 0.00127

    def today(self) -> date:
        """The as-of date: the pinned as_of, else today's date in UTC."""
        return self.as_of or datetime.now(UTC).date()

    # Plausibility of incoming records (app.services.records.plausibility): beyond these a record is
    # refused with a 422.  The crack bound is physical (a fuselage panel, not a unit slip: 5 m
    # is a value in mm sent as m); it must lie above critical_crack_m, since a crack found beyond
    # the critical one is exactly what must be recorded.
    max_crack_length_m: Annotated[float, Field(gt=0)] = 0.5
    max_stress_range_mpa: Annotated[float, Field(gt=0)] = 1000.0
    # How far a flight or an inspection may lie in the future (clocks of other systems differ).
    clock_skew_seconds: Annotated[float, Field(ge=0)] = 300.0
    # No flight or inspection is dated before this (a date read from an epoch 0 or a typo's
    # century); as-of dates start here too.
    earliest_record_date: date = date(1950, 1, 1)
    # An inspection whose finding lies more than this many standard deviations (the forecast's
    # spread and the sizing error together, app.services.forecasts.assessment) from its tail's forecast
    # is stored but flagged.
    inspection_flag_z: Annotated[float, Field(gt=0)] = 3.0

    # Promotion gate (app.services.jobs.promotion): a retrained candidate replaces the active
    # version only if its mean |% error| on the held-out inspections exceeds the active
    # version's on the same inspections by at most the larger of gate_max_error_increase_pct
    # percentage points and gate_max_error_increase_ratio times the active's error (a fleet
    # whose tails scatter has a large held-out error at the fleet's rate, and a noisy one); a
    # first version (none active) only if it is at most gate_max_error_pct.
    gate_max_error_pct: Annotated[float, Field(gt=0)] = 50.0
    gate_max_error_increase_pct: Annotated[float, Field(ge=0)] = 1.0
    gate_max_error_increase_ratio: Annotated[float, Field(ge=0)] = 0.25

    # Logs (app.logs): one JSON object per line, or plain text for a terminal.
    log_format: Literal["json", "text"] = "json"
    log_level: Literal["DEBUG", "INFO", "WARNING", "ERROR"] = "INFO"

    def law(self) -> ParisLaw:
        law = ParisLaw(
            c=self.paris_c,
            m=self.paris_m,
            geometry_factor=self.geometry_factor,
            initial_crack_m=self.initial_crack_m,
            critical_crack_m=self.critical_crack_m,
            gamma=self.walker_gamma,
        )
        return law if self.material is None else law_for(self.material, law, self.materials_file)

    def sizing(self) -> SizingError:
        return SizingError(self.sizing_relative_sd, self.sizing_absolute_sd_m)

    @model_validator(mode="after")
    def _valid_law(self) -> Settings:
        law = self.law()  # raises ValueError naming the bad constant
        if self.growth_law == "nasgro":
            if law.nasgro is None:
                raise ValueError(
                    "growth_law nasgro needs a material whose row has NASGRO terms (the shipped "
                    "table has none: a row of FLEETPINN_MATERIALS_FILE, docs/api.md); material "
                    f"is {self.material!r}"
                )
            if self.learn_paris:
                raise ValueError("learn_paris fits paris or walker, not the nasgro law")
        if self.max_crack_length_m <= self.critical_crack_m:
            raise ValueError(
                f"max_crack_length_m ({self.max_crack_length_m}) must be > critical_crack_m "
                f"({self.critical_crack_m})"
            )
        return self

    @field_validator("materials_file")
    @classmethod
    def _readable_materials(cls, path: Path | None) -> Path | None:
        if path is not None:
            user_table(path)  # MaterialsFileError naming the file, line, material and column
        return path

    @field_validator("kernel", "optimizer")
    @classmethod
    def _known_choice(cls, value: str, info: ValidationInfo) -> str:
        allowed = _CHOICES[info.field_name or ""]()
        if value not in allowed:
            raise ValueError(f"{info.field_name} must be one of {allowed}")
        return value


@lru_cache
def get_settings() -> Settings:
    return Settings()
