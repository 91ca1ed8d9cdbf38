"""Sampled forecasts of many tails at once: the crack now under posterior draws and the risk.

Sample k pairs posterior weight draw theta_k (model.uncertainty.LaplacePosterior.sample(samples,
seed); no posterior: the fitted weights) with future usage draw k of each tail.  crack_samples
marches each history once per theta_k; sample_risk starts sample k's future from its own crack
now and summarises the samples per tail (model.prognosis.probabilistic_forecast).  Each tail's
future draws come from its own FutureLoads, so its result does not depend on which other tails
are sampled with it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from model import forecast as fc
from model.block_bootstrap import BlockPools
from model.hybrid import CrackGrowthModel
from model.integrate import LoadHistory
from model.path_drift import PathDrift
from model.power_mean import power_mean
from model.prognosis import (
    LANES_PER_MARCH,
    probabilistic_forecast,
    sample_groups,
    weight_draws,
)
from model.uncertainty import LaplacePosterior, flat_parameters

# Tails x band points sampled together (the band tensor holds samples times as many floats).
BAND_VALUES = 60_000


def crack_samples(
    model: CrackGrowthModel,
    posterior: LaplacePosterior | None,
    loads: LoadHistory,
    initial_crack_m: Tensor,
    *,
    samples: int,
    seed: int,
    growth_factor: Tensor | None = None,
) -> Tensor:
    """(samples, aircraft) crack in m after each history under sample k's weights (those of
    probabilistic_forecast for the same samples and seed: prognosis.weight_draws, shared by
    WEIGHT_SHARING samples where growth factors are given) and, where given, sample k's own growth
    factors growth_factor[k] (samples, aircraft) (a tail's posterior, model.tracking; default the
    loads').  Without a posterior the fitted weights march.  A march past fracture reads
    the held crack (model.physics).  Past the measured cracks, sample k under its own
    shape of the model's extrapolation (ModelSpec.extrapolation; those of
    probabilistic_forecast for the same samples and seed).

    initial_crack_m: (aircraft,) m.  Raises ValueError for samples < 1.
    """
    cracks = _marched_samples(
        model, posterior, loads, initial_crack_m, samples, seed, growth_factor
    )
    extrapolation = model.spec.extrapolation
    if extrapolation is None:
        return cracks
    return extrapolation.beyond(cracks, extrapolation.draws(samples, seed))


def _marched_samples(
    model: CrackGrowthModel,
    posterior: LaplacePosterior | None,
    loads: LoadHistory,
    initial_crack_m: Tensor,
    samples: int,
    seed: int,
    growth_factor: Tensor | None,
) -> Tensor:
    if samples < 1:
        raise ValueError(f"samples must be >= 1, got {samples}")
    rows = torch.arange(len(initial_crack_m))
    if posterior is None and growth_factor is None:
        with torch.no_grad():
            now = model.trajectory(loads, initial_crack_m)[rows, loads.lengths]
        return now.expand(samples, -1).clone()
    if posterior is None:
        assert growth_factor is not None
        return _factor_lanes(model, loads, initial_crack_m, growth_factor)
    shared = growth_factor is not None
    draws = weight_draws(posterior, flat_parameters(model), samples, seed, shared)
    aircraft = len(initial_crack_m)
    out = torch.empty(samples, aircraft, dtype=torch.float64)
    stress = model.loads_for(loads).stress_range_mpa.to(torch.float64)
    initial = initial_crack_m.to(torch.float64)
    with torch.no_grad():
        for ks in sample_groups(samples, aircraft, True, shared):
            n = len(ks)
            factor = (
                loads.growth_factor
                if growth_factor is None
                else growth_factor[ks].reshape(-1).to(torch.float64)
            )
            lengths = loads.lengths.repeat(n)
            # a fleet's one sample a march marches its history as it is: a copy per sample was
            # ~1 s of a 300-tail refill's 200 marches of 7,300 flights
            lanes = stress if n == 1 else stress.repeat(n, 1)
            ends = (torch.arange(n * aircraft), lengths)
            now = model.trajectory_with(
                draws[ks[0]], lanes, lengths, initial.repeat(n), factor, ends
            )
            out[ks] = now.view(n, aircraft)
    return out


# growth factors marched per tail, from which every sample's crack is interpolated
FACTOR_GRID_POINTS = 33


def _factor_lanes(
    model: CrackGrowthModel, loads: LoadHistory, initial_crack_m: Tensor, growth_factor: Tensor
) -> Tensor:
    """crack_samples under the fitted weights.  Each tail marches FACTOR_GRID_POINTS factors
    evenly over its samples' range and every sample reads its crack from them: Paris' law makes
    a**(1 - m/2) linear in the factor f under a constant load (model.physics.paris_closed_form),
    so that is what is interpolated, linearly in f; samples between a grid crack below the
    held crack and one at it (no longer linear) march themselves.  tests/model/
    test_fleet_sampling.py bounds the error; one lane per sample cost 200 x 13 ms for one
    7,300-flight tail."""
    samples, aircraft = growth_factor.shape
    f = growth_factor.to(torch.float64)  # (samples, aircraft)
    tails = torch.arange(aircraft).expand(samples, -1)
    if samples <= FACTOR_GRID_POINTS:
        return _march_pairs(model, loads, initial_crack_m, tails.reshape(-1), f.reshape(-1)).view(
            samples, aircraft
        )
    lo, span = f.min(dim=0).values, f.max(dim=0).values - f.min(dim=0).values
    steps = torch.linspace(0.0, 1.0, FACTOR_GRID_POINTS, dtype=torch.float64)
    grid = lo[None, :] + span[None, :] * steps[:, None]  # (points, aircraft)
    grid_tails = torch.arange(aircraft).expand(FACTOR_GRID_POINTS, -1).reshape(-1)
    crack = _march_pairs(model, loads, initial_crack_m, grid_tails, grid.reshape(-1))
    crack = crack.view(FACTOR_GRID_POINTS, aircraft)
    power = 1.0 - model.spec.law.m / 2.0
    if abs(power) < 1e-6:
        power = 1e-6  # m = 2: a**p ~ 1 + p ln a, the same interpolation as ln a
    position = torch.where(span > 0, (f - lo) / span.clamp_min(1e-300), 0.0)
    position = position * (FACTOR_GRID_POINTS - 1)
    below = position.floor().long().clamp(0, FACTOR_GRID_POINTS - 2)
    frac = position - below
    low, high = crack.gather(0, below), crack.gather(0, below + 1)
    out = torch.empty_like(low)
    power_mean(
        low.contiguous().numpy(),
        high.contiguous().numpy(),
        frac.contiguous().numpy(),
        power,
        out.numpy(),
    )
    held = model.spec.law.held_crack_m
    kink = (high >= held) & (low < held)
    if bool(kink.any()):
        out[kink] = _march_pairs(model, loads, initial_crack_m, tails[kink], f[kink])
    return out


def _march_pairs(
    model: CrackGrowthModel,
    loads: LoadHistory,
    initial_crack_m: Tensor,
    tails: Tensor,
    growth_factor: Tensor,
) -> Tensor:
    """(pairs,) crack after the history of tails[j] under growth_factor[j], every pair a lane
    of a few compiled marches."""
    out = torch.empty(len(tails), dtype=torch.float64)
    stress = model.loads_for(loads).stress_range_mpa.to(torch.float64)
    initial = initial_crack_m.to(torch.float64)
    with torch.no_grad():
        for start in range(0, len(tails), LANES_PER_MARCH):
            part = tails[start : start + LANES_PER_MARCH]
            lengths = loads.lengths[part]
            factor = growth_factor[start : start + LANES_PER_MARCH]
            ends = (torch.arange(len(part)), lengths)
            out[start : start + len(part)] = model(
                stress[part], lengths, initial[part], factor, at=ends
            )
    return out


class StackedLoads:
    """Per-tail future loads (each its own n_flights and seed) stacked, zero-padded to the
    longest: a tail's draws do not depend on which other tails are sampled with it.  Resampled
    loads (all parts model.forecast.ResampledLoads, as the service's) are drawn together in one
    compiled pass."""

    def __init__(self, parts: Sequence[fc.FutureLoads]) -> None:
        if not parts:
            raise ValueError("parts: at least one tail's future loads are needed")
        self.parts = list(parts)
        self.n_flights = max(p.n_flights for p in self.parts)
        self.aircraft = sum(p.aircraft for p in self.parts)
        resampled = [p for p in self.parts if isinstance(p, fc.ResampledLoads)]
        self._pools = (
            BlockPools.stacked([p.pools for p in resampled])
            if len(resampled) == len(self.parts)
            else None
        )

    def draw(self, sample: int) -> np.ndarray:
        """(aircraft, n_flights) stress ranges in MPa of sample `sample`, zero past each part."""
        if self._pools is not None:
            return self._pools.draw(sample, self.n_flights)
        out = np.zeros((self.aircraft, self.n_flights))
        row = 0
        for part in self.parts:
            out[row : row + part.aircraft, : part.n_flights] = part.draw(sample)
            row += part.aircraft
        return out


def daily_flights(horizon_days: int, flights_per_day: float) -> np.ndarray:
    """(horizon_days + 1,) flights flown by the end of day d: floor(d * flights_per_day)."""
    return np.floor(np.arange(horizon_days + 1) * flights_per_day).astype(np.int64)


def report_days(horizon_days: int, bands: bool, marks: Sequence[int] | None = None) -> np.ndarray:
    """Days (from the origin) a tail reports quantiles at: every day with `bands`, else day 0 and
    its `marks` (each in [0, horizon_days])."""
    if bands:
        return np.arange(horizon_days + 1)
    days = np.unique(np.array([0, *(marks or ())], dtype=np.int64))
    if days[-1] > horizon_days:
        raise ValueError(f"marks must lie in [0, {horizon_days}], got {days[-1]}")
    return days


def band_chunks(
    rates: Sequence[float],
    horizon_days: int,
    bands: bool,
    max_values: int = BAND_VALUES,
    marks: Sequence[Sequence[int]] | None = None,
) -> list[list[int]]:
    """Indices of tails sampled together: all of them when each reports day 0 only; else tails
    of similar rates together (their report points coincide), at most max_values tails x points.
    marks: per tail, the days it reports besides day 0 (without `bands`)."""
    if not bands and marks is None:
        return [list(range(len(rates)))]
    chunks: list[list[int]] = []
    points: set[int] = set()
    for i in sorted(range(len(rates)), key=lambda i: rates[i]):
        days = report_days(horizon_days, bands, None if marks is None else marks[i])
        mine = set(np.floor(days * rates[i]).astype(np.int64).tolist())
        union = points | mine
        if chunks and len(union) * (len(chunks[-1]) + 1) <= max_values:
            chunks[-1].append(i)
            points = union
        else:
            chunks.append([i])
            points = mine
    return chunks


@dataclass(frozen=True)
class TailRisk:
    """One tail's sampled summary over a horizon; not finite: not reached / not defined.

    crack_now_m: (p05, p50, p95) after the last flight; prob_critical: share of samples at
    a_crit within the horizon; flights_to_critical: (p05, p50, p95); inspect_by_flights: half
    the p05 flights to critical; band_m: (3, horizon_days + 1) daily p05, p50, p95, or None;
    marks_m: (3, marks) p05, p50, p95 on each of the tail's mark days, in the order given.
    """

    crack_now_m: tuple[float, float, float]
    prob_critical: float
    flights_to_critical: tuple[float, float, float]
    inspect_by_flights: float
    band_m: np.ndarray | None
    marks_m: np.ndarray


def sample_risk(
    model: CrackGrowthModel,
    posterior: LaplacePosterior | None,
    crack_now_m: np.ndarray,
    futures: Sequence[fc.FutureLoads],
    rates: Sequence[float],
    horizon_days: int,
    *,
    samples: int,
    seed: int,
    bands: bool,
    growth_factor: np.ndarray | None = None,
    marks: Sequence[Sequence[int]] | None = None,
    detectable_crack_m: float | None = None,
    drift: PathDrift | None = None,
) -> list[TailRisk]:
    """The risk of each tail i over horizon_days, its future drawn from futures[i] at rates[i]
    flights per day, sample k starting from crack_now_m[k, i] (samples, tails) m.

    With `bands`, each tail's daily quantiles over days 0..horizon_days are returned too.
    growth_factor: (samples, tails) sample k's growth factor of each tail (default 1).
    marks: per tail, days in [0, horizon_days] whose quantiles it reports (TailRisk.marks_m),
    e.g. today and the horizon's end.  crack_now_m: under the model's extrapolation, as
    crack_samples gives it.  detectable_crack_m: inspect-by by the half-life rule
    (model.prognosis.probabilistic_forecast).  drift: each tail's path drift (model.path_drift,
    on every point of its forecast).  Raises ValueError for a mark outside
    that range.
    """
    tail_marks = [list(m) for m in marks] if marks is not None else [[] for _ in rates]
    for m in tail_marks:
        report_days(horizon_days, False, m)  # raises for a mark outside the horizon
    out: dict[int, TailRisk] = {}
    for chunk in band_chunks(rates, horizon_days, bands, marks=marks):
        daily = [daily_flights(horizon_days, rates[i]) for i in chunk]
        marked = [
            np.floor(np.array(tail_marks[i], dtype=np.int64) * rates[i]).astype(np.int64)
            for i in chunk
        ]
        points = [*(daily if bands else []), *marked, np.zeros(1, dtype=np.int64)]
        report = torch.from_numpy(np.unique(np.concatenate(points)))
        result = probabilistic_forecast(
            model,
            posterior,
            StackedLoads([futures[i] for i in chunk]),
            crack_now_m=torch.from_numpy(np.ascontiguousarray(crack_now_m[:, chunk])),
            horizon_flights=torch.tensor([futures[i].n_flights for i in chunk]),
            samples=samples,
            seed=seed,
            report_flights=report,
            growth_factor=None
            if growth_factor is None
            else torch.from_numpy(np.ascontiguousarray(growth_factor[:, chunk])),
            detectable_crack_m=detectable_crack_m,
            drift=None if drift is None else drift.select(chunk),
        )
        quantiles = torch.stack([result.crack_p05_m, result.crack_p50_m, result.crack_p95_m])
        band_values = quantiles.numpy()  # (3, tails, points)
        ftc = torch.stack(
            [
                result.flights_to_critical_p05,
                result.flights_to_critical_p50,
                result.flights_to_critical_p95,
            ]
        ).numpy()  # (3, tails)
        for j, i in enumerate(chunk):
            band = None
            if bands:
                band = band_values[:, j, np.searchsorted(report.numpy(), daily[j])]
            now = band_values[:, j, 0]
            out[i] = TailRisk(
                (float(now[0]), float(now[1]), float(now[2])),
                float(result.prob_critical[j]),
                (float(ftc[0, j]), float(ftc[1, j]), float(ftc[2, j])),
                float(result.inspect_by_flights[j]),
                band,
                band_values[:, j, np.searchsorted(report.numpy(), marked[j])],
            )
    return [out[i] for i in range(len(rates))]
