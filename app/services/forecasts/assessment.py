"""How an inspection compares with its tail's forecast, and when it disagrees strongly.

The tail's crack at the inspection is predicted as forecasts predict it: the active version of
the inspection's location marched over the tail's flights flown before the inspection (their
loads as the location sees them), from the initial crack of
the segment in force (its last earlier repair's crack), at the tail's own growth rate (the p50
of its growth posterior in the forecast cache, conditioned on its stored inspections).  A
measured crack is compared in log space,

    z = (ln a_measured - ln a_forecast) / sqrt(s_forecast**2 + s_sizing(a_forecast)**2),

s_forecast: the spread of ln crack over the cached samples of the tail's crack now (model
weights and the tail's own growth rate: what makes the forecast's band), (ln p95 - ln p05) /
3.29; s_sizing: the inspection
sizing error of the version's tracking prior (else the settings').  |z| > inspection_flag_z (3)
flags it: a finding that far from the forecast is more often a wrong record (units, tail, date)
than a surprise, so it is stored but flagged in its answer, in the tail's inspections and in
the ranking.  A non-detection compares the forecast with its detection limit (threshold, or the
PoD curve's a50 with spread ln(a90 / a50) / 1.2816 in place of the sizing error): z > flag
means nothing was found where the forecast expects a crack the method finds.

Flights recorded after the inspection do not enter; flights not yet recorded before it do not
either (the prediction is the crack after the last recorded flight before the inspection).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
import torch
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.config import Settings
from app.errors import ConflictError
from app.services import models as model_service
from app.services.forecasts import forecast_cache
from app.services.forecasts.cache_rows import CacheState, Subject
from app.services.records.history import History, load_history
from app.tables import DEFAULT_LOCATION_ID, Aircraft
from model.posterior import LocationPosterior, SizingError

# a90 = a50 * exp(1.2816 sd) on a log-normal PoD curve (1.2816: the standard normal's 90 % point)
_Z90 = 1.2815515655446004
_Z95 = 1.6448536269514722

COLUMNS = ("forecast_crack_m", "forecast_z", "flagged")


@dataclass(frozen=True)
class Assessment:
    inspection_id: str
    forecast_crack_m: float | None
    forecast_z: float | None
    flagged: bool


def assess(session: Session, inspections: pd.DataFrame, settings: Settings) -> pd.DataFrame:
    """COLUMNS for each row of validated inspections (model.records shape, any tails; a
    location_id column names each row's location, else the default one), indexed like them,
    each compared with its location's active version: NaN and not flagged where there is no
    forecast (no active model at its location, an unknown tail or one without flights).  May
    fill the forecast cache (and commit), so it runs before the caller's write transaction
    begins."""
    out = pd.DataFrame(
        {"forecast_crack_m": np.nan, "forecast_z": np.nan, "flagged": False},
        index=inspections.index,
    )
    if inspections.empty:
        return out
    where = (
        inspections["location_id"]
        if "location_id" in inspections.columns
        else pd.Series(DEFAULT_LOCATION_ID, index=inspections.index)
    )
    for location_id, at_location in inspections.groupby(where.astype(int), sort=False):
        _assess_location(session, at_location, int(location_id), settings, out)
    return out


def _assess_location(
    session: Session,
    inspections: pd.DataFrame,
    location_id: int,
    settings: Settings,
    out: pd.DataFrame,
) -> None:
    """assess() for rows of one location, written into `out`: its own version, its local
    loads and its cached forecast (the crack now's spread)."""
    version = model_service.active_version_number(session, location_id)
    if version is None:
        return
    posterior = model_service.load_posterior(session, version)
    prior = posterior.tracking
    sizing = prior.sizing if prior is not None else settings.sizing()
    for tail, rows in inspections.groupby("tail", sort=False):
        aircraft_id = session.scalar(select(Aircraft.id).where(Aircraft.tail == tail))
        if aircraft_id is None:
            continue
        history = load_history(
            session,
            [aircraft_id],
            initial_crack_m=posterior.law.initial_crack_m,
            location_id=location_id,
        )
        if history is None:
            continue
        subject = Subject(aircraft_id, location_id)
        try:
            state = forecast_cache.cached_state(session, subject, version, settings)
        except ConflictError:
            continue
        predicted = _predict(posterior, history, rows["inspected_at"], _growth_p50(state))
        spread = _log_sd(state)
        for (row, inspection), forecast in zip(rows.iterrows(), predicted, strict=True):
            z = _z(inspection, forecast, spread, sizing)
            out.loc[row, "forecast_crack_m"] = forecast
            out.loc[row, "forecast_z"] = z
            measured = bool(inspection.get("detected", True))
            out.loc[row, "flagged"] = (
                abs(z) > settings.inspection_flag_z if measured else z > settings.inspection_flag_z
            )


def rows_of(frame: pd.DataFrame, assessed: pd.DataFrame) -> list[Assessment]:
    """Assessment records of `frame`'s rows (its inspection_id column) from assess()'s frame."""
    part = assessed.loc[frame.index]
    return [
        Assessment(
            str(inspection_id),
            None if pd.isna(forecast) else float(forecast),
            None if pd.isna(z) else float(z),
            bool(flagged),
        )
        for inspection_id, forecast, z, flagged in zip(
            frame["inspection_id"],
            part["forecast_crack_m"],
            part["forecast_z"],
            part["flagged"],
            strict=True,
        )
    ]


def _growth_p50(state: CacheState) -> float:
    growth = state.growth or {}
    return float(growth.get("p50", 1.0))


def _log_sd(state: CacheState) -> float:
    """The spread of ln crack now over the cached samples, from their 5 % and 95 % points
    ((q95 - q05) / 3.29, a normal's sd; robust to a few diverged draws, which count as an
    infinite crack: when more than 5 % diverge the spread is infinite and nothing is flagged)."""
    if state.crack_samples_m is None:
        return 0.0
    samples = np.frombuffer(state.crack_samples_m, np.float64)
    if samples.size < 2:
        return 0.0
    usable = np.isfinite(samples) & (samples > 0)
    logs = np.where(usable, np.log(np.where(usable, samples, 1.0)), np.inf)
    q05, q95 = np.quantile(logs, [0.05, 0.95], method="inverted_cdf")
    return float((q95 - q05) / (2 * _Z95))


def _predict(
    posterior: LocationPosterior, history: History, at: pd.Series, growth_factor: float
) -> np.ndarray:
    """The crack (len(at),) after the tail's last flight before each time in `at` (one tail)."""
    segments = history.segments
    flown = _ns(history.data.flights["flown_at"])
    inspections = history.inspections
    repair_times = np.sort(
        _ns(inspections.loc[inspections["repaired"].astype(bool), "inspected_at"])
    )
    times = _ns(at)
    before = np.searchsorted(flown, times, side="left")  # flights flown strictly before
    segment = np.searchsorted(repair_times, times, side="left")  # repairs strictly before
    loads = replace(
        segments.loads,
        growth_factor=torch.full((len(segments.tail),), growth_factor, dtype=torch.float64),
    )
    trajectory = posterior.trajectory(loads).numpy()  # (segments, flights + 1)
    steps = before - segments.start[segment]
    return trajectory[segment, steps]


def _ns(times: pd.Series) -> np.ndarray:
    """UTC times as int64 nanoseconds."""
    return times.dt.tz_convert("UTC").dt.tz_localize(None).dt.as_unit("ns").to_numpy().view("int64")


def _z(inspection: pd.Series, forecast: float, spread: float, sizing: SizingError) -> float:
    forecast_sd = float(sizing.log_sd(torch.tensor([forecast], dtype=torch.float64))[0])
    if bool(inspection.get("detected", True)):
        measured = float(inspection["crack_length_m"])
        return (math.log(measured) - math.log(forecast)) / math.hypot(spread, forecast_sd)
    a50 = inspection.get("pod_a50_m")
    if a50 is not None and not pd.isna(a50):
        limit = float(a50)
        limit_sd = math.log(float(inspection["pod_a90_m"]) / limit) / _Z90
    else:
        limit = float(inspection["detection_threshold_m"])
        limit_sd = float(sizing.log_sd(torch.tensor([limit], dtype=torch.float64))[0])
    return (math.log(forecast) - math.log(limit)) / math.hypot(spread, limit_sd)
