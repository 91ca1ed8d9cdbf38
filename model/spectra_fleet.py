"""A synthetic fleet whose flights are load spectra and whose truth is Walker's law.

The thesis fleet's missions and mixes (model.fleet) with every flight a spectrum: one
ground-air-ground cycle (the mission's stress range times the flight's lognormal scatter, from
a slightly compressive ground stress: R = -0.1) plus gust and manoeuvre cycles, as many as
the mission flies (GUSTS), each with a range of 15-45 % of the flight's GAG range and a load
ratio drawn from the mission's band (GUST_R: high-mean cruise gusts on M0 up to 0.7, taxi and
manoeuvre cycles on M2 down to -0.3), a tenth of them half cycles.  At most 10 cycles a flight.

Truth: Walker's law, da/dN = C [dK / (1 - R)**(1 - gamma)]**m, summed over the flight's cycles
with the crack held over the flight (model.growth_laws: a step of the flight's
damage-equivalent range), the thesis fleet's geometry discrepancy and growth scatter
(model.fleet.simulate_cracks).  C is scaled so that the fleet's median flight does the damage
of the thesis fleet's median flight, so cracks span a similar range.  The load ratio's weight
differs by mission, so one damage-equivalent range per flight that ignores R (what an airline
sends today: `paris_equivalent_mpa`) ranks flights of different missions wrongly.

Route changes.  After `switch_year` every tail swaps its two missions (a tail that flew k % of
its mix's first mission flies 100 - k % of it), as aircraft move between routes.  Without it a
tail's mix, and so the load ratios' weight in its damage, never changes, and a per-tail growth
factor absorbs any error in gamma: crack sizes alone could not tell gamma (measured while
building this: a calibration started at gamma 0.95 stayed there on error-free inspections).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd
import torch

from model.fleet import (
    MISSION_MIXES,
    MISSION_STRESS_MPA,
    Fleet,
    FleetConfig,
    generate_fleet,
    simulate_cracks,
)
from model.growth_laws import GROWTH_LAWS, CycleSpectrum
from model.integrate import LoadHistory
from model.physics import ParisLaw

CYCLES_PER_FLIGHT = 10
GAG_LOAD_RATIO = -0.1
# gust and manoeuvre cycles a flight of each mission flies, and their load ratios' band
GUSTS: tuple[int, ...] = (9, 6, 9, 4)
GUST_R: tuple[tuple[float, float], ...] = ((0.4, 0.7), (0.2, 0.5), (-0.3, 0.2), (0.0, 0.4))
GUST_SHARE = (0.15, 0.45)  # gust range / the flight's GAG range
HALF_CYCLE_SHARE = 0.1


@dataclass(frozen=True)
class SpectraFleetConfig:
    """The thesis fleet's config (model.fleet.FleetConfig: its law's C is rescaled, see the
    module docstring) and Walker's gamma of the truth."""

    fleet: FleetConfig = field(default_factory=FleetConfig)
    gamma: float = 0.6
    switch_year: float | None = 2.5


@dataclass(frozen=True)
class SpectraFleet:
    """A generated spectra fleet: `fleet` (model.fleet.Fleet) holds the missions, the true
    cracks, and as stress_range_mpa the true damage-equivalent range of each flight (its
    config.law the truth's C and m, so model.fleet's tools march the truth); `law` the truth
    (gamma included); `cycles` every flight's cycles."""

    fleet: Fleet
    law: ParisLaw
    cycles: CycleSpectrum

    def history(self, flights: int | None = None, growth_law: str = "walker") -> LoadHistory:
        """The fleet's recorded cycles (the first `flights` of each tail), reduced under the
        truth's constants for `growth_law` (a model's own law re-reduces them)."""
        cycles = self.cycles.pick(slice(None), flights)
        n, steps = cycles.stress_range_mpa.shape[:2]
        lengths = torch.full((n,), steps, dtype=torch.long)
        return LoadHistory.from_cycles(cycles, lengths, growth_law, self.law.constants)

    def cycles_frame(self) -> pd.DataFrame:
        """The cycle file (model.spectrum_files CYCLE_COLUMNS, and mission) of every flight:
        one row per cycle flown, flights in fleet order."""
        flights = self.fleet.flights_frame()
        count = self.cycles.count.numpy().reshape(len(flights), -1)
        flown = count > 0
        per_flight = flown.sum(axis=1)
        columns = {
            name: np.repeat(flights[name].to_numpy(), per_flight)
            for name in ("tail", "flight_id", "flown_at")
        }
        channels = (self.cycles.stress_range_mpa, self.cycles.load_ratio)
        for name, values in zip(("stress_range_mpa", "load_ratio"), channels, strict=True):
            columns[name] = values.numpy().reshape(len(flights), -1)[flown]
        columns["count"] = count[flown]
        columns["mission"] = np.repeat(flights["mission"].to_numpy(), per_flight)
        return pd.DataFrame(columns)

    def paris_equivalent_mpa(self, m: float | None = None) -> np.ndarray:
        """(aircraft, flights) one range per flight, [sum n dS**m]**(1/m) with R ignored: the
        damage-equivalent range today's single-range input carries (m: the truth's)."""
        constants = replace(self.law, m=m or self.law.m).constants
        return GROWTH_LAWS["paris"].equivalent_range(self.cycles, constants).numpy()


def _spectra(fleet: Fleet, seed: int) -> CycleSpectrum:
    rng = np.random.default_rng(np.random.SeedSequence([seed, 21]))
    n, flights = fleet.mission.shape
    shape = (n, flights, CYCLES_PER_FLIGHT)
    gag = fleet.stress_range_mpa  # mission stress times the flight's scatter
    ranges = np.zeros(shape)
    ratios = np.zeros(shape)
    counts = np.zeros(shape)
    ranges[:, :, 0], ratios[:, :, 0], counts[:, :, 0] = gag, GAG_LOAD_RATIO, 1.0
    gusts = np.asarray(GUSTS)[fleet.mission]  # (aircraft, flights)
    low = np.asarray([band[0] for band in GUST_R])[fleet.mission]
    high = np.asarray([band[1] for band in GUST_R])[fleet.mission]
    for k in range(1, CYCLES_PER_FLIGHT):
        flown = gusts >= k
        share = rng.uniform(*GUST_SHARE, size=(n, flights))
        ranges[:, :, k] = np.where(flown, share * gag, 0.0)
        ratios[:, :, k] = np.where(flown, low + (high - low) * rng.random((n, flights)), 0.0)
        half = rng.random((n, flights)) < HALF_CYCLE_SHARE
        counts[:, :, k] = np.where(flown, np.where(half, 0.5, 1.0), 0.0)
    return CycleSpectrum(
        torch.from_numpy(ranges), torch.from_numpy(ratios), torch.from_numpy(counts)
    )


def _switch_routes(fleet: Fleet, at_flight: int) -> Fleet:
    """Each tail's two missions swapped from flight `at_flight` on (module docstring)."""
    first = np.asarray([mix[0] for mix in MISSION_MIXES.values()])
    second = np.asarray([mix[1] for mix in MISSION_MIXES.values()])
    index = {name: i for i, name in enumerate(MISSION_MIXES)}
    mix = np.asarray([index[m] for m in fleet.mix])
    later = fleet.mission[:, at_flight:]
    swapped = np.where(later == first[mix][:, None], second[mix][:, None], first[mix][:, None])
    mission = fleet.mission.copy()
    mission[:, at_flight:] = swapped
    nominal = np.asarray(MISSION_STRESS_MPA)
    scatter = fleet.stress_range_mpa / nominal[fleet.mission]
    return replace(fleet, mission=mission, stress_range_mpa=nominal[mission] * scatter)


def generate_spectra_fleet(config: SpectraFleetConfig | None = None) -> SpectraFleet:
    """The fleet of the module docstring; deterministic for config.fleet.seed."""
    config = config or SpectraFleetConfig()
    base = generate_fleet(config.fleet)
    if config.switch_year is not None:
        base = _switch_routes(base, int(config.switch_year * config.fleet.flights_per_year))
    cycles = _spectra(base, config.fleet.seed)
    law = replace(config.fleet.law, gamma=config.gamma)
    walker = GROWTH_LAWS["walker"].equivalent_range(cycles, law.constants).numpy()
    # the median flight's damage as the thesis fleet's (its missions' nominal GAG alone)
    nominal = np.asarray(MISSION_STRESS_MPA)[base.mission]
    c = law.c * float(np.median(nominal**law.m) / np.median(walker**law.m))
    law = replace(law, c=c)
    crack = simulate_cracks(
        walker,
        law,
        config.fleet.discrepancy,
        base.growth_factor,
        config.fleet.geometry,
    )
    fleet = replace(
        base,
        config=replace(config.fleet, law=replace(law, gamma=1.0)),
        stress_range_mpa=walker,
        crack_length_m=crack,
    )
    return SpectraFleet(fleet, law, cycles)
