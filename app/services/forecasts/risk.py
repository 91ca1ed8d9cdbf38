"""The sampled risk of cached tails, per horizon, as their cache states carry it.

Sampling is the location's posterior's (model.posterior); here its results become JSON in the state (risk, bands),
which app.services.forecasts.cache_rows stores.  Future usage of a tail without a plan: blocks of one day of its own recent flights
(model.forecast.ResampledLoads), seeded per tail so that a single forecast and the ranking draw
the same futures.  Inspection interval (inspect_by): damage-tolerance practice (MIL-STD-1530C)
inspects at half the remaining time to critical; taken conservatively as half the p05 flights to
critical, null where the p05 lies beyond the horizon.

Time as engineers read it: a horizon counts from the as-of date (today, or a pinned date), while
the march starts at the tail's origin (its last recorded flight, or a later repair).  So a tail
whose data stopped `lead` days before the as-of date is sampled over lead + horizon days from its
origin, and its risk is stored under the key "lead+horizon"; the as-of date moves once a day, so
a row keeps only its newest few keys.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import date, datetime
from typing import Any, Protocol

import numpy as np

from app import budget, metrics
from app.config import Settings
from app.services.dates import date_after, lead_days, overdue
from app.services.forecasts.cache_rows import CacheState
from app.services.forecasts.tail_status import PastCritical, past_critical
from model import forecast as fc
from model.posterior import LocationPosterior, TailRisk

Quantiles = tuple[float | None, float | None, float | None]  # (p05, p50, p95); None: not finite
Dates = tuple[datetime | None, datetime | None, datetime | None]
# Horizons (lead+horizon keys) a cached row keeps: the as-of date moves daily.
_KEPT_KEYS = 6


def risk_key(lead: int, horizon_days: int) -> str:
    return f"{lead}+{horizon_days}"


@dataclass(frozen=True)
class Risk:
    """Sampled summary of one tail over lead_days + horizon_days from its origin (flights counted
    from the origin; the horizon from the as-of date, lead_days after the origin's date).

    crack_now: crack after the last flight (p05, p50, p95); crack_as_of: on the as-of date;
    crack_at_horizon: at the horizon's end; prob_critical: share of samples at a_crit by the
    horizon's end; flights_to_critical: quantiles, None where not reached by then;
    inspect_by_flights: half the p05 flights to critical, None where beyond the horizon.
    """

    horizon_days: int
    lead_days: int
    samples: int
    crack_now: Quantiles
    crack_as_of: Quantiles
    crack_at_horizon: Quantiles
    prob_critical: float
    flights_to_critical: tuple[int | None, int | None, int | None]
    inspect_by_flights: int | None

    @property
    def span_days(self) -> int:
        """Days sampled from the origin: to the as-of date, then the horizon."""
        return self.lead_days + self.horizon_days

    def to_json(self) -> dict[str, Any]:
        return {
            "horizon_days": self.horizon_days,
            "lead_days": self.lead_days,
            "samples": self.samples,
            "crack_now": list(self.crack_now),
            "crack_as_of": list(self.crack_as_of),
            "crack_at_horizon": list(self.crack_at_horizon),
            "prob_critical": self.prob_critical,
            "flights_to_critical": list(self.flights_to_critical),
            "inspect_by_flights": self.inspect_by_flights,
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Risk:
        def quantiles(name: str) -> Quantiles:
            p05, p50, p95 = data[name]
            return (p05, p50, p95)

        f05, f50, f95 = data["flights_to_critical"]
        return cls(
            int(data["horizon_days"]),
            int(data["lead_days"]),
            int(data["samples"]),
            quantiles("crack_now"),
            quantiles("crack_as_of"),
            quantiles("crack_at_horizon"),
            float(data["prob_critical"]),
            (f05, f50, f95),
            data["inspect_by_flights"],
        )


def critical_dates(origin: datetime, risk: Risk, rate: float) -> Dates:
    f05, f50, f95 = risk.flights_to_critical
    return (
        date_after(origin, f05, rate),
        date_after(origin, f50, rate),
        date_after(origin, f95, rate),
    )


@dataclass(frozen=True)
class Decisions:
    """What a row's risk decides on the as-of date, alike in a tail's forecast, an aircraft's
    line per location and the ranking: the dates the crack reaches a_crit (p05, p50, p95), the
    inspect-by date, whether it is overdue, and whether the p50 crack is past a_crit."""

    critical_dates: Dates
    inspect_by: datetime | None
    overdue: bool
    past: PastCritical


def decisions(
    origin: datetime, risk: Risk, rate: float, critical_crack_m: float, as_of: date
) -> Decisions:
    """Decisions of `risk`, sampled from `origin` at `rate` flights a day."""
    inspect_by = date_after(origin, risk.inspect_by_flights, rate)
    dates = critical_dates(origin, risk, rate)
    past = past_critical(risk.crack_as_of[1], critical_crack_m, dates[1], origin)
    return Decisions(dates, inspect_by, overdue(inspect_by, as_of), past)


def tail_seed(settings: Settings, aircraft_id: int) -> int:
    """The seed of one tail's future-usage draws: the same in single forecasts and the ranking."""
    return zlib.crc32(f"{settings.forecast_seed}:{aircraft_id}".encode())


def finite(value: float) -> float | None:
    # math, not numpy: a numpy call per value cost to_band's 330,000 values of a refill ~0.5 s
    return float(value) if math.isfinite(value) else None


def _flights(value: float) -> int | None:
    return int(value) if np.isfinite(value) else None


def _quantiles(values: Sequence[float] | np.ndarray) -> Quantiles:
    return (finite(values[0]), finite(values[1]), finite(values[2]))


def to_risk(sampled: TailRisk, horizon_days: int, lead: int, samples: int) -> Risk:
    """The risk of a tail sampled over lead + horizon_days with marks [lead, lead + horizon]."""
    now, ftc, marks = sampled.crack_now_m, sampled.flights_to_critical, sampled.marks_m
    return Risk(
        horizon_days=horizon_days,
        lead_days=lead,
        samples=samples,
        crack_now=_quantiles(now),
        crack_as_of=_quantiles(marks[:, 0]),
        crack_at_horizon=_quantiles(marks[:, 1]),
        prob_critical=sampled.prob_critical,
        flights_to_critical=(_flights(ftc[0]), _flights(ftc[1]), _flights(ftc[2])),
        inspect_by_flights=_flights(sampled.inspect_by_flights),
    )


def to_band(sampled: TailRisk) -> dict[str, list[float | None]]:
    """Daily {p05, p50, p95} lists (None: not finite) of a tail sampled with bands."""
    assert sampled.band_m is not None
    # one tolist per quantile, not a numpy scalar per day: 330,000 values in a 300-tail refill
    return {
        name: [finite(v) for v in sampled.band_m[q].tolist()]
        for q, name in enumerate(("p05", "p50", "p95"))
    }


def stored_samples(
    states: Sequence[CacheState], samples: int
) -> tuple[np.ndarray, np.ndarray | None]:
    """The cached rows' crack-now samples (samples, tails) and each sample's growth factor
    (samples, tails; 1 for a row without tracking), None where no row is tracked."""
    cracks = np.stack([np.frombuffer(s.crack_samples_m or b"", np.float64) for s in states], axis=1)
    if all(s.growth_samples is None for s in states):
        return cracks, None
    log_factors = [
        np.frombuffer(s.growth_samples, np.float64)
        if s.growth_samples is not None
        else np.zeros(samples)
        for s in states
    ]
    return cracks, np.exp(np.stack(log_factors, axis=1))


def sample_states(
    posterior: LocationPosterior,
    states: Sequence[CacheState],
    futures: Sequence[fc.FutureLoads],
    rates: Sequence[float],
    horizon_days: int,
    settings: Settings,
    *,
    bands: bool,
    leads: Sequence[int],
) -> list[TailRisk]:
    """Sample the risk of cached states over horizon_days from their origins, each from its own
    crack-now samples, with quantiles at day leads[i] and at the end (TailRisk.marks_m)."""
    cracks, growth = stored_samples(states, settings.forecast_samples)
    return posterior.risk(
        cracks,
        futures,
        rates,
        horizon_days,
        samples=settings.forecast_samples,
        seed=settings.forecast_seed,
        bands=bands,
        growth_factor=growth,
        marks=[[lead, horizon_days] for lead in leads],
        drift_from_m=[drift_from(state) for state in states],
        tail_seeds=[tail_seed(settings, state.aircraft_id) for state in states],
        detectable_crack_m=settings.detectable_crack_m
        if settings.inspect_by_rule == "half_life"
        else None,
    )


def inspect_rule(settings: Settings) -> str:
    """The inspect-by rule in words, as answers name it (settings.inspect_by_rule)."""
    if settings.inspect_by_rule == "half_life":
        return (
            "half-life: midway through the p05 crack's life from detectable "
            f"({settings.detectable_crack_m:g} m) to critical"
        )
    return "half the p05 time to critical"


def drift_from(state: CacheState) -> float:
    """Where the row's forecast drifts beyond its posterior from: its tail's latest measured
    crack, kept with the row (a row stored without one drifts not at all)."""
    return float((state.growth or {}).get("since_crack_m", math.inf))


def _recent_futures(
    states: Sequence[CacheState], horizon_days: int, settings: Settings
) -> list[fc.FutureLoads]:
    """Each tail's future resampled from its recent flights, in blocks of one day of them."""
    futures: list[fc.FutureLoads] = []
    for state in states:
        recent = np.frombuffer(state.recent_stress_mpa or b"", np.float64)
        futures.append(
            fc.ResampledLoads(
                [recent],
                fc.flights_within(horizon_days, state.flights_per_day),
                seed=tail_seed(settings, state.aircraft_id),
                block_flights=max(1, round(state.flights_per_day)),
            )
        )
    return futures


def fill_risk(
    posterior: LocationPosterior,
    states: Sequence[CacheState],
    horizon_days: int,
    settings: Settings,
    *,
    bands: bool,
    as_of: date,
) -> list[CacheState]:
    """Sample and store the risk (and with `bands` the daily bands from the origin) of these
    states over horizon_days after the as-of date; states are sampled together per lead, as
    many at a time as fit max_sampling_bytes (app.budget; a tail's draws do not depend on the
    tails sampled with it).  Between those pieces the request's deadline is checked: on
    DeadlineExceeded the states sampled so far keep their new risk (the caller may store them).

    A state whose span holds more flights per draw than a request may sample (app.budget.
    check_span) is not sampled and is returned: a fill ahead (a retrain's, the worker's) must
    not spend minutes and gigabytes on risk that every request for it is refused (a test's
    clock of 400 flights a day, years before today); a request checks first (check_sampled)."""
    by_lead: dict[int, list[CacheState]] = {}
    refused: list[CacheState] = []
    for state in states:
        lead = lead_days(state.origin, as_of)
        if budget.within_span(
            fc.flights_within(lead + horizon_days, state.flights_per_day), settings
        ):
            by_lead.setdefault(lead, []).append(state)
            continue
        refused.append(state)
        if bands and state.bands is None:
            state.bands = {}  # considered: not pending for the worker (cache_rows.pending)
    metrics.RISK_SAMPLED.inc(len(states) - len(refused))
    for lead, group in sorted(by_lead.items()):
        span = lead + horizon_days
        flights = fc.flights_within(span, max(s.flights_per_day for s in group))
        step = budget.tails_per_march(flights, settings)
        if step < len(group):  # pieces of similar rates: fewer report points each
            group = sorted(group, key=lambda s: s.flights_per_day)
        for start in range(0, len(group), step):
            budget.check()
            part = group[start : start + step]
            sampled = sample_states(
                posterior,
                part,
                _recent_futures(part, span, settings),
                [s.flights_per_day for s in part],
                span,
                settings,
                bands=bands,
                leads=[lead] * len(part),
            )
            key = risk_key(lead, horizon_days)
            for state, tail in zip(part, sampled, strict=True):
                risk = to_risk(tail, horizon_days, lead, settings.forecast_samples)
                state.risk = _newest(state.risk, key, risk.to_json())
                if bands:
                    band = {"samples": risk.samples, **to_band(tail)}
                    state.bands = _newest(state.bands, key, band)
    return refused


def check_sampled(
    states: Sequence[CacheState], horizon_days: int, settings: Settings, as_of: date
) -> None:
    """Raise app.budget.OutOfBounds (422 naming as_of) where one of these states' span after the
    as-of date exceeds the sampling budget: the request that needs its risk is refused, as
    fill_risk never samples it."""
    for state in states:
        lead = lead_days(state.origin, as_of)
        rate = state.flights_per_day
        flights = fc.flights_within(lead + horizon_days, rate)
        budget.check_span(flights, lead, horizon_days, rate, settings)


def _newest(stored: dict[str, Any] | None, key: str, value: Any) -> dict[str, Any]:
    """stored with key set to value last, keeping the _KEPT_KEYS newest keys."""
    kept = {k: v for k, v in (stored or {}).items() if k != key}
    return {**dict(list(kept.items())[-(_KEPT_KEYS - 1) :]), key: value}


class StoredRisk(Protocol):
    """A cached row's origin and stored risk (a CacheState, or a ranking's plain snapshot)."""

    @property
    def origin(self) -> datetime: ...

    @property
    def risk(self) -> dict[str, Any] | None: ...


def cached_risk(
    state: StoredRisk, horizon_days: int, settings: Settings, as_of: date
) -> Risk | None:
    """The stored risk of this horizon after the as-of date, None where missing or of another
    sample count."""
    key = risk_key(lead_days(state.origin, as_of), horizon_days)
    data = (state.risk or {}).get(key)
    if data is None or data["samples"] != settings.forecast_samples:
        return None
    return Risk.from_json(data)


def cached_band(
    state: CacheState, horizon_days: int, settings: Settings, as_of: date
) -> dict[str, Any] | None:
    """The stored daily bands (from the origin) of this horizon, as cached_risk."""
    band = (state.bands or {}).get(risk_key(lead_days(state.origin, as_of), horizon_days))
    if band is None or band.get("samples") != settings.forecast_samples:
        return None
    return dict(band)
