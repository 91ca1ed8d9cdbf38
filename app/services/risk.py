"""The sampled risk of cached tails, stored per horizon in their forecast rows.

Sampling is model.fleet_sampling's; here its results become JSON in the row (risk, bands) and
dates.  Future usage of a tail without a plan: blocks of one day of its own recent flights
(model.forecast.ResampledLoads), seeded per tail so that a single forecast and the ranking draw
the same futures.  Inspection interval (inspect_by): damage-tolerance practice (MIL-STD-1530C)
inspects at half the remaining time to critical; taken conservatively as half the p05 flights to
critical, null where the p05 lies beyond the horizon.
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import Any

import numpy as np
import pandas as pd

from app.config import Settings
from app.tables import Forecast
from model import forecast as fc
from model.fleet_sampling import TailRisk, sample_risk
from model.hybrid import CrackGrowthModel
from model.uncertainty import LaplacePosterior

_EPOCH = datetime(1970, 1, 1, tzinfo=UTC)

Quantiles = tuple[float | None, float | None, float | None]  # (p05, p50, p95); None: not finite
Dates = tuple[datetime | None, datetime | None, datetime | None]


@dataclass(frozen=True)
class Risk:
    """Sampled summary of one tail over a horizon (flights counted from its origin).

    crack_now: crack after the last flight (p05, p50, p95); prob_critical: share of samples at
    a_crit within the horizon; flights_to_critical: quantiles, None where not reached within it;
    inspect_by_flights: half the p05 flights to critical, None where beyond the horizon.
    """

    horizon_days: int
    samples: int
    crack_now: Quantiles
    prob_critical: float
    flights_to_critical: tuple[int | None, int | None, int | None]
    inspect_by_flights: int | None

    def to_json(self) -> dict[str, Any]:
        return {
            "horizon_days": self.horizon_days,
            "samples": self.samples,
            "crack_now": list(self.crack_now),
            "prob_critical": self.prob_critical,
            "flights_to_critical": list(self.flights_to_critical),
            "inspect_by_flights": self.inspect_by_flights,
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Risk:
        p05, p50, p95 = data["crack_now"]
        f05, f50, f95 = data["flights_to_critical"]
        return cls(
            int(data["horizon_days"]),
            int(data["samples"]),
            (p05, p50, p95),
            float(data["prob_critical"]),
            (f05, f50, f95),
            data["inspect_by_flights"],
        )


def ns(value: datetime) -> int:
    return int(pd.Timestamp(value).as_unit("ns").value)


def from_ns(value_ns: int) -> datetime:
    return _EPOCH + timedelta(microseconds=value_ns // 1000)


def date_after(origin: datetime, flights: int | None, rate: float) -> datetime | None:
    """The date `flights` flights after origin at `rate` a day; None for None."""
    if flights is None:
        return None
    return from_ns(fc.date_after_flights(ns(origin), flights, rate))


def critical_dates(origin: datetime, risk: Risk, rate: float) -> Dates:
    f05, f50, f95 = risk.flights_to_critical
    return (
        date_after(origin, f05, rate),
        date_after(origin, f50, rate),
        date_after(origin, f95, rate),
    )


def tail_seed(settings: Settings, aircraft_id: int) -> int:
    """The seed of one tail's future-usage draws: the same in single forecasts and the ranking."""
    return zlib.crc32(f"{settings.forecast_seed}:{aircraft_id}".encode())


def finite(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def _flights(value: float) -> int | None:
    return int(value) if np.isfinite(value) else None


def to_risk(sampled: TailRisk, horizon_days: int, samples: int) -> Risk:
    now, ftc = sampled.crack_now_m, sampled.flights_to_critical
    return Risk(
        horizon_days=horizon_days,
        samples=samples,
        crack_now=(finite(now[0]), finite(now[1]), finite(now[2])),
        prob_critical=sampled.prob_critical,
        flights_to_critical=(_flights(ftc[0]), _flights(ftc[1]), _flights(ftc[2])),
        inspect_by_flights=_flights(sampled.inspect_by_flights),
    )


def to_band(sampled: TailRisk) -> dict[str, list[float | None]]:
    """Daily {p05, p50, p95} lists (None: not finite) of a tail sampled with bands."""
    assert sampled.band_m is not None
    return {
        name: [finite(v) for v in sampled.band_m[q]] for q, name in enumerate(("p05", "p50", "p95"))
    }


def sample_states(
    model: CrackGrowthModel,
    posterior: LaplacePosterior | None,
    states: Sequence[Forecast],
    futures: Sequence[fc.FutureLoads],
    rates: Sequence[float],
    horizon_days: int,
    settings: Settings,
    *,
    bands: bool,
) -> list[TailRisk]:
    """Sample the risk of cached states, each from its own crack-now samples."""
    cracks = np.stack(
        [np.frombuffer(s.crack_samples_m or b"", np.float64) for s in states], axis=1
    )  # (samples, tails)
    growth = None
    if any(s.growth_samples is not None for s in states):
        samples = settings.forecast_samples
        growth = np.exp(
            np.stack(
                [
                    np.frombuffer(s.growth_samples, np.float64)
                    if s.growth_samples is not None
                    else np.zeros(samples)
                    for s in states
                ],
                axis=1,
            )
        )  # (samples, tails) each tail's own growth factor draws
    return sample_risk(
        model,
        posterior,
        cracks,
        futures,
        rates,
        horizon_days,
        samples=settings.forecast_samples,
        seed=settings.forecast_seed,
        bands=bands,
        growth_factor=growth,
    )


def _recent_futures(
    states: Sequence[Forecast], horizon_days: int, settings: Settings
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
    model: CrackGrowthModel,
    posterior: LaplacePosterior | None,
    states: Sequence[Forecast],
    horizon_days: int,
    settings: Settings,
    *,
    bands: bool,
) -> None:
    """Sample and store the risk (and with `bands` the daily bands) of these states."""
    if not states:
        return
    futures = _recent_futures(states, horizon_days, settings)
    rates = [s.flights_per_day for s in states]
    sampled = sample_states(
        model, posterior, states, futures, rates, horizon_days, settings, bands=bands
    )
    key = str(horizon_days)
    for state, tail in zip(states, sampled, strict=True):
        risk = to_risk(tail, horizon_days, settings.forecast_samples)
        state.risk = {**(state.risk or {}), key: risk.to_json()}
        if bands:
            state.bands = {**(state.bands or {}), key: {"samples": risk.samples, **to_band(tail)}}


def cached_risk(state: Forecast, horizon_days: int, settings: Settings) -> Risk | None:
    """The stored risk of this horizon, None where missing or of another sample count."""
    data = (state.risk or {}).get(str(horizon_days))
    if data is None or data["samples"] != settings.forecast_samples:
        return None
    return Risk.from_json(data)
