"""Synthetic fleet of thesis chapter 4 and its inspection scenarios.

Fleet.  Four missions load a fuselage control point with far-field stress ranges 92.5, 100, 110
and 130 MPa (M0..M3).  Three mission mixes fly 100 aircraft each; aircraft k (k = 0..99) of a
mix flies k % of the mix's first mission and (100 - k) % of its second, in a random order drawn
per aircraft.  The thesis fixes mix A = (M0, M3) only; here

    A = (M0, M3)   spans the whole fleet: 0.0067 m (99 % M0) to 0.033 m (all M3),
    B = (M1, M2)   the mild mix: 0.0075-0.0094 m,
    C = (M2, M3)   the severe mix: 0.0095-0.034 m,

so year-5 cracks span 0.0067-0.034 m for seed 0 (thesis: ~0.005-0.035 m; median 0.010 m,
90th percentile 0.024 m) and both ends of the range hold many aircraft, which keeps "uniform
coverage" and "true distribution" inspection samples distinct.  (With C = (M0, M2) two thirds of
the fleet would sit below 0.0093 m.)

Scatter.  Each flight's stress range is its mission's times a mean-one lognormal factor,
exp(s z - s**2 / 2), z ~ N(0, 1), s = `stress_scatter` (default 0.08): gusts and payload vary
from flight to flight; the damage rate, ~dS**3.8, varies ~30 % from flight to flight and is
3.5 % higher on average than at the mission's nominal stress (E[X**m] = exp(m (m-1) s**2 / 2)),
which carries the all-M3 aircraft from 0.029 m to 0.034 m.

Truth.  One forward-Euler step of Paris' law per flight (thesis constants, model.physics):
a_t = a_{t-1} + C (F(a_{t-1}) F0 dS_t sqrt(pi a_{t-1}))**m with F(a) = 1 by default.  With
`discrepancy` = beta > 0 the truth holds a crack-length-dependent geometry factor the physics
kernel lacks, F(a) = 1 + beta (a - a0) / (a_crit - a0); beta = DISCREPANCY_20PCT (0.06) makes
the physics alone under-predict the largest year-5 crack (0.043 m true) by 19 %, the median by
1 %: the missing physics matters where cracks are long.  `geometry` picks other shapes of the
truth's factor, for fleets whose discrepancy does something else beyond the inspected cracks
(true_geometry_factor): "flat" F = 1 + beta at every crack length (a constant the physics
misses), "secant" F = sqrt(sec(pi a / 2W)) (a through crack in a panel of width 2W = 2
`discrepancy` m: flat at short cracks, accelerating towards the panel's edge), "falloff"
F = 1 + beta sin(pi (a - a0) / (a_crit - a0)) (rising over short cracks, back to 1 at a_crit,
as a crack growing towards a stiffener), "fall" F = 1 - beta (a - a0) / (a_crit - a0) (load
shed to a doubler or stringer as the crack grows), or a table of the truth's own F
(model.geometry.GeometryTable: a shape drawn from a prior, benchmarks/sbc.py).

Scenarios (thesis Tables 4.2 and 4.5).  I, continuous monitoring: 60 aircraft observed every
1460 / 120 / 28 / 4 flights (yearly / monthly / weekly / daily: 5 / 60 / 260 / 1825 points
each).  II, scheduled inspection: n aircraft inspected once after the last flight, chosen
biased-small, true-distribution, uniform-coverage or biased-large.  Samples index a sub-batch of
the fleet, so a model trains on the inspected aircraft only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import torch

from model.geometry import GeometryTable
from model.integrate import LoadHistory, Observations
from model.physics import ParisLaw

MISSION_STRESS_MPA: tuple[float, ...] = (92.5, 100.0, 110.0, 130.0)
MISSION_MIXES: dict[str, tuple[int, int]] = {"A": (0, 3), "B": (1, 2), "C": (2, 3)}
DAYS_PER_YEAR = 365
# beta of the geometry-factor discrepancy that makes physics alone err by ~20 % at year 5
# on the default fleet (measured: tests/model/test_fleet.py).
DISCREPANCY_20PCT = 0.06
MONITORING_PERIODS: dict[str, int] = {"yearly": 1460, "monthly": 120, "weekly": 28, "daily": 4}
SELECTIONS = ("biased-small", "true-distribution", "uniform-coverage", "biased-large")
# biased-small/large draw from this fraction of the fleet at the small/large end
BIASED_POOL_FRACTION = 1 / 3
# shapes of the truth's geometry factor (true_geometry_factor)
GEOMETRIES = ("linear", "flat", "secant", "falloff", "fall")
# a secant crack reaching this fraction of the panel's half width has torn through it
_SECANT_LIMIT = 0.98


def true_geometry_factor(
    crack_length_m: np.ndarray,
    law: ParisLaw,
    geometry: str | GeometryTable,
    discrepancy: float,
) -> np.ndarray:
    """The truth's geometry factor F(a) of shape `geometry` (module docstring) and size
    `discrepancy` (beta; for "secant" the panel's half width W in m), or a table's F.  Raises
    ValueError for an unknown shape."""
    a = np.asarray(crack_length_m, dtype=np.float64)
    if isinstance(geometry, GeometryTable):
        return np.interp(a, geometry.crack_length_m, geometry.factor)
    t = (a - law.initial_crack_m) / (law.critical_crack_m - law.initial_crack_m)
    if geometry == "linear":
        return 1.0 + discrepancy * t
    if geometry == "flat":
        return np.full_like(a, 1.0 + discrepancy)
    if geometry == "secant":
        x = np.minimum(a / discrepancy, _SECANT_LIMIT) * math.pi / 2
        return np.sqrt(1.0 / np.cos(x))
    if geometry == "falloff":
        return 1.0 + discrepancy * np.sin(math.pi * np.clip(t, 0.0, 1.0))
    if geometry == "fall":
        return 1.0 - discrepancy * np.clip(t, 0.0, 1.0)
    raise ValueError(f"geometry must be one of {GEOMETRIES}, got {geometry!r}")


@dataclass(frozen=True)
class FleetConfig:
    """Size and randomness of a synthetic fleet; the defaults are the thesis fleet.

    aircraft_per_mix: aircraft k of a mix flies k / aircraft_per_mix of its first mission.
    years, flights_per_day: schedule (365-day years).  stress_scatter: sigma of the mean-one
    lognormal per-flight factor on stress range.  discrepancy: beta of the truth's geometry
    factor F(a) = 1 + beta (a - a0) / (a_crit - a0); 0 = plain Paris law.  growth_scatter:
    sd of ln of each aircraft's own growth-rate factor on Paris C (replicate specimens of one
    alloy differ by tens of percent; 0 = the thesis's world, tails differ by loads only).
    start: UTC time of every aircraft's first flight; flights are evenly spaced over each day.
    """

    aircraft_per_mix: int = 100
    years: int = 5
    flights_per_day: int = 4
    stress_scatter: float = 0.08
    discrepancy: float = 0.0
    growth_scatter: float = 0.0
    law: ParisLaw = field(default_factory=ParisLaw)
    geometry: str | GeometryTable = "linear"
    start: str = "2020-01-01T00:00:00Z"
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("aircraft_per_mix", "years", "flights_per_day"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        for name in ("stress_scatter", "discrepancy", "growth_scatter"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if not isinstance(self.geometry, GeometryTable) and self.geometry not in GEOMETRIES:
            raise ValueError(f"geometry must be one of {GEOMETRIES}, got {self.geometry!r}")
        if self.geometry == "secant" and not self.discrepancy > 0:
            raise ValueError("a secant geometry needs discrepancy (the half width, m) > 0")
        if self.geometry == "fall" and not self.discrepancy < 1:
            raise ValueError("a falling geometry needs discrepancy < 1 (F stays > 0)")

    @property
    def flights(self) -> int:
        return self.years * DAYS_PER_YEAR * self.flights_per_day

    @property
    def flights_per_year(self) -> int:
        return DAYS_PER_YEAR * self.flights_per_day


@dataclass(frozen=True)
class Fleet:
    """A generated fleet.  Aircraft are ordered mix by mix (A, B, C), k ascending within a mix.

    stress_range_mpa: (aircraft, flights); mission: (aircraft, flights) mission index 0..3;
    crack_length_m: (aircraft, flights + 1) true crack, index t = after t flights;
    mix: (aircraft,) "A"/"B"/"C"; share_pct: (aircraft,) k, % of flights on the mix's first
    mission (rounded down when aircraft_per_mix is not 100); tails: "N001", ...; flown_at: (flights,) UTC times, the same schedule for all.
    """

    config: FleetConfig
    stress_range_mpa: np.ndarray
    mission: np.ndarray
    crack_length_m: np.ndarray
    mix: np.ndarray
    share_pct: np.ndarray
    tails: list[str]
    flown_at: pd.DatetimeIndex
    growth_factor: np.ndarray  # (aircraft,) true factor on Paris C, 1 without growth_scatter

    @property
    def size(self) -> int:
        return len(self.tails)

    @property
    def final_crack_m(self) -> np.ndarray:  # (aircraft,)
        return self.crack_length_m[:, -1]

    @property
    def loads(self) -> LoadHistory:
        stress = torch.from_numpy(self.stress_range_mpa)
        return LoadHistory(stress, torch.full((self.size,), stress.shape[1], dtype=torch.long))

    def flights_frame(self) -> pd.DataFrame:
        """Long-format flights (model.records contract): tail, flight_id ("1".. per tail),
        flown_at, stress_range_mpa, mission ("M0".."M3"), tail by tail in flight order."""
        n, flights = self.stress_range_mpa.shape
        names = np.array([f"M{i}" for i in range(len(MISSION_STRESS_MPA))])
        return pd.DataFrame(
            {
                "tail": np.repeat(np.array(self.tails), flights),
                "flight_id": np.tile(np.arange(1, flights + 1).astype(str), n),
                "flown_at": np.tile(self.flown_at.to_numpy(), n),
                "stress_range_mpa": self.stress_range_mpa.reshape(-1),
                "mission": names[self.mission.reshape(-1)],
            }
        ).astype({"flown_at": "datetime64[ns, UTC]"})

    def inspections_frame(self, sample: Sample) -> pd.DataFrame:
        """Long-format inspections of a sample: each observation after t flights is dated halfway
        between flight t and flight t + 1, so exactly t flights precede it."""
        obs = sample.observations
        fleet_aircraft = sample.aircraft[obs.aircraft].numpy()
        flights = obs.flights.numpy()
        step = (
            self.flown_at[1] - self.flown_at[0] if len(self.flown_at) > 1 else pd.Timedelta(1, "h")
        )
        inspected_at = self.flown_at[0] + (flights - 0.5) * step
        return pd.DataFrame(
            {
                "tail": np.array(self.tails)[fleet_aircraft],
                "inspection_id": [f"I{f}" for f in flights],
                "inspected_at": inspected_at,
                "crack_length_m": obs.crack_length_m.numpy(),
            }
        )


@dataclass(frozen=True)
class Sample:
    """Crack observations of some aircraft of a fleet.

    aircraft: (n,) fleet indices of the observed aircraft; loads: their load histories (the
    sub-batch); observations: index into that sub-batch (observations.aircraft is 0..n-1).
    """

    aircraft: torch.Tensor
    loads: LoadHistory
    observations: Observations


def simulate_cracks(
    stress_range_mpa: np.ndarray,
    law: ParisLaw,
    discrepancy: float = 0.0,
    growth_factor: np.ndarray | None = None,
    geometry: str | GeometryTable = "linear",
) -> np.ndarray:
    """True crack length (aircraft, flights + 1) in m from stress ranges (aircraft, flights) in MPa.

    a_t = a_{t-1} + C (F(a_{t-1}) F0 dS_t sqrt(pi a_{t-1}))**m, F(a) = 1 + beta (a - a0)/(a_crit - a0),
    beta = discrepancy (or another `geometry`'s F, true_geometry_factor), C times each
    aircraft's growth_factor (aircraft,) if given; one Euler
    step per flight, vectorised over aircraft.  A crack that outgrows 10 a_crit (a failed part,
    e.g. a fast-growing tail of a scattered fleet) is held there.
    """
    n, flights = stress_range_mpa.shape
    crack = np.empty((n, flights + 1), dtype=np.float64)
    crack[:, 0] = law.initial_crack_m
    # dS**m once for all flights; each step then costs a few vector ops over aircraft
    stress_term = (law.geometry_factor * stress_range_mpa) ** law.m  # (aircraft, flights)
    if growth_factor is not None:
        stress_term = stress_term * np.asarray(growth_factor, dtype=np.float64)[:, None]
    a = crack[:, 0].copy()
    for t in range(flights):
        factor = true_geometry_factor(a, law, geometry, discrepancy)
        a = a + law.c * stress_term[:, t] * (factor**2 * math.pi * a) ** (law.m / 2)
        a = np.minimum(a, law.held_crack_m)
        crack[:, t + 1] = a
    return crack


def generate_fleet(config: FleetConfig | None = None) -> Fleet:
    """The synthetic fleet of thesis chapter 4 (see the module docstring); deterministic for
    config.seed.  Raises ValueError for an invalid config."""
    config = config or FleetConfig()
    per_mix, flights = config.aircraft_per_mix, config.flights
    order_rng, scatter_rng, growth_rng = (
        np.random.default_rng(s) for s in np.random.SeedSequence(config.seed).spawn(3)
    )
    mix_names = np.repeat(np.array(list(MISSION_MIXES)), per_mix)
    share = np.tile(np.arange(per_mix), len(MISSION_MIXES))  # k
    first = np.repeat([m[0] for m in MISSION_MIXES.values()], per_mix)
    second = np.repeat([m[1] for m in MISSION_MIXES.values()], per_mix)
    first_flights = np.rint(share / per_mix * flights).astype(np.int64)
    in_order = np.where(
        np.arange(flights)[None, :] < first_flights[:, None], first[:, None], second[:, None]
    )
    mission = order_rng.permuted(in_order, axis=1).astype(np.int8)  # (aircraft, flights)
    s = config.stress_scatter
    factor = np.exp(s * scatter_rng.standard_normal(mission.shape) - s * s / 2)
    stress = np.asarray(MISSION_STRESS_MPA)[mission] * factor
    n = len(share)
    growth = np.exp(config.growth_scatter * growth_rng.standard_normal(n))
    crack = simulate_cracks(stress, config.law, config.discrepancy, growth, config.geometry)
    width = max(3, len(str(n)))
    step = pd.Timedelta(days=1) / config.flights_per_day
    flown_at = pd.Timestamp(config.start).tz_convert("UTC") + step * np.arange(flights)
    return Fleet(
        config=config,
        stress_range_mpa=stress,
        mission=mission,
        crack_length_m=crack,
        mix=mix_names,
        share_pct=share * 100 // per_mix,
        tails=[f"N{i + 1:0{width}d}" for i in range(n)],
        flown_at=pd.DatetimeIndex(flown_at).as_unit("ns"),
        growth_factor=growth,
    )


def inspect_at(
    fleet: Fleet, aircraft: np.ndarray, flights: np.ndarray, noise_sd: float = 0.0, seed: int = 0
) -> Sample:
    """Observe `aircraft` (fleet indices) after each of `flights` flights, with multiplicative
    sizing noise observed = true * exp(noise_sd z).  Raises ValueError for noise_sd < 0."""
    if not noise_sd >= 0:
        raise ValueError(f"noise_sd must be >= 0, got {noise_sd}")
    aircraft = np.asarray(aircraft, dtype=np.int64)
    local = np.repeat(np.arange(len(aircraft)), len(flights))
    steps = np.tile(flights, len(aircraft))
    crack = fleet.crack_length_m[aircraft[local], steps]
    if noise_sd > 0:
        # multiplicative and always positive; ~noise_sd relative sd for small noise_sd
        z = np.random.default_rng(seed).standard_normal(crack.shape)
        crack = crack * np.exp(noise_sd * z)
    chosen = torch.from_numpy(aircraft)
    return Sample(
        aircraft=chosen,
        loads=fleet.loads.select(chosen),
        observations=Observations(
            torch.from_numpy(local), torch.from_numpy(steps), torch.from_numpy(crack.copy())
        ),
    )


def continuous_monitoring(
    fleet: Fleet, period: str, aircraft: int = 60, noise_sd: float = 0.0, seed: int = 0
) -> Sample:
    """Scenario I: `aircraft` monitored aircraft observed every MONITORING_PERIODS[period] flights.

    The monitored aircraft are evenly spaced in fleet order (index i * size // aircraft), i.e.
    every 5th of the thesis fleet: 20 per mix with k = 0, 5, ..., 95, covering every mix and the
    whole share range.  noise_sd: multiplicative noise, observed = true * exp(noise_sd z).
    Raises ValueError for an unknown period or more aircraft than the fleet has.
    """
    if period not in MONITORING_PERIODS:
        raise ValueError(f"period must be one of {tuple(MONITORING_PERIODS)}, got {period!r}")
    if not 1 <= aircraft <= fleet.size:
        raise ValueError(f"aircraft must lie in [1, {fleet.size}], got {aircraft}")
    every = MONITORING_PERIODS[period]
    steps = np.arange(every, fleet.stress_range_mpa.shape[1] + 1, every)
    if len(steps) == 0:
        raise ValueError(f"the fleet flies fewer than one {period} period ({every} flights)")
    chosen = np.arange(aircraft) * fleet.size // aircraft
    return inspect_at(fleet, chosen, steps, noise_sd, seed)


def scheduled_inspection(
    fleet: Fleet, count: int, selection: str, noise_sd: float = 0.0, seed: int = 0
) -> Sample:
    """Scenario II: `count` aircraft inspected once, after their last flight (end of year 5).

    selection: "true-distribution" = a random sample of the fleet; "uniform-coverage" = for
    targets evenly spaced over [min, max] of the true final crack, the nearest aircraft not yet
    chosen (the two ends first, so both extremes are inspected); "biased-small" / "biased-large" = a random sample from the BIASED_POOL_FRACTION of the
    fleet (at least `count` aircraft) with the smallest / largest final crack.  Random choices
    use `seed`.  Raises ValueError for an unknown selection or a count outside [1, fleet size].
    """
    if selection not in SELECTIONS:
        raise ValueError(f"selection must be one of {SELECTIONS}, got {selection!r}")
    if not 1 <= count <= fleet.size:
        raise ValueError(f"count must lie in [1, {fleet.size}], got {count}")
    rng = np.random.default_rng(seed)
    final = fleet.final_crack_m
    if selection == "true-distribution":
        chosen = rng.choice(fleet.size, count, replace=False)
    elif selection == "uniform-coverage":
        free = np.ones(fleet.size, dtype=bool)
        picks = []
        targets = np.linspace(final.min(), final.max(), count)
        # the ends first, so the smallest and largest cracks are always inspected
        for target in (*targets[[0, -1]][:count], *targets[1:-1]):
            distance = np.where(free, np.abs(final - target), np.inf)
            pick = int(np.argmin(distance))
            free[pick] = False
            picks.append(pick)
        chosen = np.array(picks)
    else:
        pool_size = max(count, math.ceil(fleet.size * BIASED_POOL_FRACTION))
        ranked = np.argsort(final, kind="stable")
        pool = ranked[:pool_size] if selection == "biased-small" else ranked[-pool_size:]
        chosen = rng.choice(pool, count, replace=False)
    chosen = np.sort(chosen)
    return inspect_at(fleet, chosen, np.array([fleet.stress_range_mpa.shape[1]]), noise_sd, seed)
