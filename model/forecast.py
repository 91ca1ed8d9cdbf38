"""Forecasts: project a tail's future loads, march the model ahead, find the time to critical.

Pure numpy/torch: the service reads the records and stores the answers.  The projection is
deterministic: future flights repeat, in order, the stress ranges the tail flew in its recent
window (so its mission mix carries on), at the rate it flew them (flights per day).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Protocol

import numpy as np
import torch
from torch import Tensor

from model.block_bootstrap import BlockPools
from model.hybrid import CrackGrowthModel
from model.integrate import LoadHistory

NS_PER_DAY = 86_400 * 10**9


@dataclass(frozen=True)
class Utilization:
    """How a tail has been flown lately: flights per day over its utilization window and the
    stress ranges (MPa) of its load window."""

    flights_per_day: float
    recent_stress_mpa: np.ndarray  # (flights in window,)


def recent_utilization(
    flown_at_ns: np.ndarray,
    stress_range_mpa: np.ndarray,
    window_days: float,
    load_window_days: float | None = None,
) -> Utilization:
    """Utilization over the window (last flight - window_days, last flight]; the stress ranges
    over the load window (last flight - load_window_days, last flight], at least the window
    (None: the window itself).  A flight's damage goes as its range**m, a heavy tail that a
    short sample under-represents, while the rate follows a change of route within weeks.

    flown_at_ns: (flights,) sorted epoch nanoseconds; stress_range_mpa: (flights,) in that order.
    Rate = flights in window / days covered, where a history shorter than the window covers
    max(last - first, 1 day).  Raises ValueError for an empty history or a window <= 0.
    """
    if len(flown_at_ns) == 0:
        raise ValueError("flown_at_ns holds no flight: utilization needs at least one")
    if len(flown_at_ns) != len(stress_range_mpa):
        raise ValueError("flown_at_ns and stress_range_mpa must have the same length")
    if not window_days > 0:
        raise ValueError(f"window_days must be > 0, got {window_days}")
    last, first = int(flown_at_ns[-1]), int(flown_at_ns[0])
    in_window = flown_at_ns > last - int(window_days * NS_PER_DAY)
    loads_days = max(window_days, load_window_days or window_days)
    in_loads = flown_at_ns > last - int(loads_days * NS_PER_DAY)
    covered_days = min(float(window_days), max((last - first) / NS_PER_DAY, 1.0))
    return Utilization(
        float(in_window.sum()) / covered_days,
        np.asarray(stress_range_mpa[in_loads], dtype=np.float64),
    )


def project_loads(recent_stress_mpa: np.ndarray, n_flights: int, start: int = 0) -> np.ndarray:
    """Future stress ranges (n_flights,): the recent ones repeated in order from position `start`."""
    if len(recent_stress_mpa) == 0:
        raise ValueError("recent_stress_mpa is empty: nothing to project from")
    if n_flights < 0:
        raise ValueError(f"n_flights must be >= 0, got {n_flights}")
    positions = (start + np.arange(n_flights)) % len(recent_stress_mpa)
    return np.asarray(recent_stress_mpa, dtype=np.float64)[positions]


def march_ahead(
    model: CrackGrowthModel,
    crack_now_m: Tensor,
    future_stress_mpa: Tensor,
    growth_factor: Tensor | None = None,
) -> Tensor:
    """Crack (aircraft, flights + 1) in m from crack_now_m (aircraft,) over future_stress_mpa
    (aircraft, flights), each aircraft at its growth factor (aircraft,) (default 1)."""
    lengths = torch.full(
        (future_stress_mpa.shape[0],), future_stress_mpa.shape[1], dtype=torch.long
    )
    with torch.no_grad():
        return model.trajectory(
            LoadHistory(future_stress_mpa.to(torch.float64), lengths, growth_factor=growth_factor),
            crack_now_m.to(torch.float64),
        )


def first_at_or_above(trajectory_m: Tensor, critical_crack_m: float) -> Tensor:
    """Index (aircraft,) of the first trajectory point >= critical_crack_m, -1 where none.

    NaN (a diverged march) counts as reached: the crack has outgrown the model's range.
    """
    reached = (trajectory_m >= critical_crack_m) | torch.isnan(trajectory_m)
    any_reached = reached.any(dim=1)
    first = reached.to(torch.int8).argmax(dim=1)
    return torch.where(any_reached, first, torch.full_like(first, -1))


def flights_to_critical(
    model: CrackGrowthModel,
    crack_now_m: Sequence[float],
    recent_stress_mpa: Sequence[np.ndarray],
    critical_crack_m: float,
    max_flights: Sequence[int],
    chunk_flights: int = 2048,
    growth_factor: Sequence[float] | None = None,
) -> list[int | None]:
    """Flights after now until each aircraft's crack reaches critical_crack_m, or None past its cap.

    Marches the aircraft together in chunks of projected flights (project_loads), dropping each
    aircraft as it reaches the critical crack or its max_flights cap.  0 when already critical.
    growth_factor: each aircraft's factor on the growth rate (default 1).
    """
    n = len(crack_now_m)
    if not len(recent_stress_mpa) == len(max_flights) == n:
        raise ValueError(
            "crack_now_m, recent_stress_mpa and max_flights need one entry per aircraft"
        )
    if chunk_flights < 1:
        raise ValueError(f"chunk_flights must be >= 1, got {chunk_flights}")
    answer: list[int | None] = [None] * n
    crack = torch.tensor(list(crack_now_m), dtype=torch.float64)
    caps = np.asarray(max_flights, dtype=np.int64)
    active = []
    for i in range(n):
        if crack[i] >= critical_crack_m:
            answer[i] = 0
        elif caps[i] > 0:
            active.append(i)
    done = 0
    while active:
        steps = int(min(chunk_flights, max(caps[active]) - done))
        future = np.stack([project_loads(recent_stress_mpa[i], steps, done) for i in active])
        factor = (
            None
            if growth_factor is None
            else torch.tensor([float(growth_factor[i]) for i in active], dtype=torch.float64)
        )
        trajectory = march_ahead(model, crack[active], torch.from_numpy(future), factor)
        first = first_at_or_above(trajectory, critical_crack_m)
        still = []
        for row, i in enumerate(active):
            hit = int(first[row])
            if hit >= 0 and done + hit <= caps[i]:
                answer[i] = done + hit
            elif done + steps < caps[i]:
                crack[i] = trajectory[row, -1]
                still.append(i)
        active = still
        done += steps
    return answer


def daily_points(
    trajectory_m: np.ndarray, flights_per_day: float, horizon_days: int, critical_crack_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """Days (d = 0..horizon_days) and projected flights (floor(d * rate)) to report a trajectory at.

    trajectory_m: (flights + 1,) crack after k projected flights.  The points stop at the first one
    whose crack is at or above critical_crack_m (beyond it the model has no meaning).
    Returns (days, flights), both int64.
    """
    days = np.arange(horizon_days + 1, dtype=np.int64)
    flights = np.minimum(np.floor(days * flights_per_day).astype(np.int64), len(trajectory_m) - 1)
    reached = np.flatnonzero(
        (trajectory_m[flights] >= critical_crack_m) | np.isnan(trajectory_m[flights])
    )
    if len(reached):
        days, flights = days[: reached[0] + 1], flights[: reached[0] + 1]
    return days, flights


def flights_within(horizon_days: int, flights_per_day: float) -> int:
    """Projected flights in horizon_days at flights_per_day."""
    return int(np.floor(horizon_days * flights_per_day))


def date_after_flights(origin_ns: int, flights: int, flights_per_day: float) -> int:
    """Epoch ns of the flights-th projected flight after origin at a steady rate."""
    return origin_ns + round(flights / flights_per_day * NS_PER_DAY)


# ---------------------------------------------------------------------------------------------
# Sampled future usage, for probabilistic forecasts (model/prognosis.py).  Each source draws
# sample number k as an (aircraft, flights) array, deterministic for (seed, k), so a forecast
# never holds all samples' loads at once (200 samples x 300 tails x 1,460 flights = 700 MB).


class FutureLoads(Protocol):
    """A source of future stress ranges: `draw(k)` is sample k, (aircraft, n_flights) in MPa."""

    @property
    def n_flights(self) -> int: ...

    @property
    def aircraft(self) -> int: ...

    def draw(self, sample: int) -> np.ndarray: ...


@dataclass(frozen=True)
class ResampledLoads:
    """Future flights block-bootstrapped from each tail's own recent stress ranges.

    Sample k of tail i concatenates blocks of `block_flights` consecutive flights of its recent
    window (circular: a block may wrap from the last flight to the first), each starting at a
    uniformly drawn flight, cut to n_flights.  Blocks of a day's flights (block_flights = flights
    per day) keep whatever order the tail flies within a day; the mission mix carries on with
    its sampling spread.  Deterministic for (seed, i, k): a tail's draws do not depend on the
    other tails' (model.block_bootstrap).
    """

    recent_stress_mpa: Sequence[np.ndarray]  # per tail: (flights in window,)
    n_flights: int
    seed: int = 0
    block_flights: int = 4

    def __post_init__(self) -> None:
        if not self.recent_stress_mpa:
            raise ValueError("recent_stress_mpa must hold at least one tail")
        if any(len(r) == 0 for r in self.recent_stress_mpa):
            raise ValueError("recent_stress_mpa: every tail needs at least one recent flight")
        if self.n_flights < 0:
            raise ValueError(f"n_flights must be >= 0, got {self.n_flights}")
        if self.block_flights < 1:
            raise ValueError(f"block_flights must be >= 1, got {self.block_flights}")
        if self.seed < 0:
            raise ValueError(f"seed must be >= 0, got {self.seed}")

    @property
    def aircraft(self) -> int:
        return len(self.recent_stress_mpa)

    @cached_property
    def pools(self) -> BlockPools:
        """The tails as rows of one compiled draw (model.block_bootstrap)."""
        return BlockPools.of(self.recent_stress_mpa, self.seed, self.block_flights, self.n_flights)

    def draw(self, sample: int) -> np.ndarray:
        """Sample `sample` of the future stress ranges, (aircraft, n_flights) in MPa."""
        return self.pools.draw(sample, self.n_flights)


@dataclass(frozen=True)
class PlannedUtilization:
    """A planned utilization: flights per day and the mission mix as stress-range samples.

    stress_range_mpa: (k,) stress ranges in MPa (e.g. one per mission, or flights of a
    representative schedule); weights: (k,) their shares (None: equal); each future flight draws
    one of them independently.  The rate sets how many flights a horizon holds (flights_within).
    """

    flights_per_day: float
    stress_range_mpa: np.ndarray
    weights: np.ndarray | None = None

    def __post_init__(self) -> None:
        if not self.flights_per_day > 0:
            raise ValueError(f"flights_per_day must be > 0, got {self.flights_per_day}")
        stress = np.asarray(self.stress_range_mpa, dtype=np.float64)
        if stress.ndim != 1 or len(stress) == 0 or not bool((stress > 0).all()):
            raise ValueError("stress_range_mpa must be a non-empty 1-d array of values > 0")
        if self.weights is not None:
            weights = np.asarray(self.weights, dtype=np.float64)
            if weights.shape != stress.shape or not bool((weights >= 0).all()):
                raise ValueError("weights must be >= 0 with one entry per stress range")
            if not weights.sum() > 0:
                raise ValueError("weights must not all be zero")


@dataclass(frozen=True)
class PlannedLoads:
    """Future flights of `aircraft` tails drawn i.i.d. from a planned mission mix."""

    plan: PlannedUtilization
    aircraft: int
    n_flights: int
    seed: int = 0

    def __post_init__(self) -> None:
        if self.aircraft < 1:
            raise ValueError(f"aircraft must be >= 1, got {self.aircraft}")
        if self.n_flights < 0:
            raise ValueError(f"n_flights must be >= 0, got {self.n_flights}")

    def draw(self, sample: int) -> np.ndarray:
        """Sample `sample` of the future stress ranges, (aircraft, n_flights) in MPa."""
        if sample < 0:
            raise ValueError(f"sample must be >= 0, got {sample}")
        rng = np.random.default_rng([self.seed, sample])
        stress = np.asarray(self.plan.stress_range_mpa, dtype=np.float64)
        weights = None if self.plan.weights is None else np.asarray(self.plan.weights, float)
        p = None if weights is None else weights / weights.sum()
        return rng.choice(stress, size=(self.aircraft, self.n_flights), p=p)


@dataclass(frozen=True)
class FixedLoads:
    """The same future stress ranges (aircraft, n_flights) for every sample (e.g. project_loads)."""

    stress_range_mpa: np.ndarray

    def __post_init__(self) -> None:
        if np.asarray(self.stress_range_mpa).ndim != 2:
            raise ValueError("stress_range_mpa must be (aircraft, flights)")

    @property
    def aircraft(self) -> int:
        return int(self.stress_range_mpa.shape[0])

    @property
    def n_flights(self) -> int:
        return int(self.stress_range_mpa.shape[1])

    def draw(self, sample: int) -> np.ndarray:
        return np.asarray(self.stress_range_mpa, dtype=np.float64)
