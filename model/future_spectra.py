"""Future usage as whole flights: planned missions and resampled recent flights that carry their
cycles, each entering a forecast as the flight's damage-equivalent range under the forecasting
model's own law (model.growth_laws), so a learned gamma weighs the future's load ratios as it
weighed the past's.

model.forecast's PlannedUtilization and ResampledLoads draw flights from a pool of one value per
flight; built here, each value is a whole flight (its GAG, gust and manoeuvre cycles together),
never a cycle drawn apart from its flight.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from model.cycle_counting import FlightCycles, spectrum_of
from model.forecast import PlannedUtilization, ResampledLoads
from model.growth_laws import GROWTH_LAWS
from model.hybrid import CrackGrowthModel


def flight_ranges(model: CrackGrowthModel, flights: Sequence[FlightCycles]) -> np.ndarray:
    """(flights,) each flight's damage-equivalent range under the model's law, MPa."""
    if not flights:
        return np.zeros(0)
    law = GROWTH_LAWS[model.spec.growth_law]
    return law.equivalent_range(spectrum_of(flights), model.spec.law.constants)[0].numpy()


def planned_spectra(
    model: CrackGrowthModel,
    flights_per_day: float,
    missions: Sequence[FlightCycles],
    weights: np.ndarray | None = None,
) -> PlannedUtilization:
    """A planned utilization whose missions are flights with their cycles (one per mission),
    drawn with `weights` (None: equal)."""
    return PlannedUtilization(flights_per_day, flight_ranges(model, missions), weights)


def resampled_spectra(
    model: CrackGrowthModel,
    recent: Sequence[Sequence[FlightCycles]],
    n_flights: int,
    seed: int = 0,
    block_flights: int = 4,
) -> ResampledLoads:
    """Future flights block-bootstrapped from each tail's recent flights (`recent`: per tail,
    its flights in order, with their cycles)."""
    pools = [flight_ranges(model, flights) for flights in recent]
    return ResampledLoads(pools, n_flights, seed, block_flights)
