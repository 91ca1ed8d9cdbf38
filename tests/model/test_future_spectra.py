"""Future usage carries whole flights: planned missions and resampled recent flights with their
cycles, under the forecasting model's own law."""

from __future__ import annotations

import numpy as np
import torch

from model.cycle_counting import FlightCycles, spectrum_of
from model.forecast import FixedLoads, PlannedLoads
from model.future_spectra import flight_ranges, planned_spectra, resampled_spectra
from model.hybrid import CrackGrowthModel, ModelSpec
from model.integrate import LoadHistory
from model.physics import ParisLaw
from model.prognosis import probabilistic_forecast

# a cruise mission (high-mean gusts) and a low-level one (manoeuvres about a low mean)
CRUISE = FlightCycles(np.array([100.0, 30.0, 25.0]), np.array([-0.1, 0.6, 0.7]), np.ones(3))
LOW = FlightCycles(np.array([95.0, 35.0, 30.0]), np.array([-0.1, -0.2, 0.0]), np.ones(3))


def _model(growth_law: str, gamma: float) -> CrackGrowthModel:
    law = ParisLaw(gamma=gamma)
    return CrackGrowthModel(ModelSpec(kernel="physics", law=law, growth_law=growth_law))


def test_whole_flights_enter_as_their_range_under_the_models_law() -> None:
    walker = _model("walker", 0.5)
    ranges = flight_ranges(walker, [CRUISE, LOW])
    # the same as the model's own reduction of those flights as a history
    history = LoadHistory.from_cycles(
        spectrum_of([CRUISE, LOW]), torch.tensor([2]), "walker", walker.spec.law.constants
    )
    np.testing.assert_array_equal(ranges, walker.loads_for(history).stress_range_mpa[0].numpy())
    # a learned gamma weighs the load ratios: the cruise flight's gusts count for more
    paris = flight_ranges(_model("paris", 1.0), [CRUISE, LOW])
    assert ranges[0] / paris[0] > ranges[1] / paris[1]


def test_a_plan_of_mission_spectra_forecasts_as_its_flights_marched() -> None:
    walker = _model("walker", 0.5)
    plan = planned_spectra(walker, 4.0, [CRUISE, LOW], np.array([3.0, 1.0]))
    future = PlannedLoads(plan, aircraft=2, n_flights=3000, seed=7)
    now = torch.tensor([0.01, 0.012], dtype=torch.float64)
    result = probabilistic_forecast(walker, None, future, crack_now_m=now, samples=3)
    # the same draws as fixed future loads, marched by the model itself
    fixed = probabilistic_forecast(
        walker, None, FixedLoads(future.draw(0)), crack_now_m=now, samples=1
    )
    direct = walker.trajectory(
        LoadHistory(torch.from_numpy(future.draw(0)), torch.tensor([3000, 3000])), now
    )[:, -1]
    # (the forecast reads its p50 off a quantile of the samples: agreement to 1e-7)
    np.testing.assert_allclose(fixed.crack_p50_m[:, -1].numpy(), direct.numpy(), rtol=1e-7)
    assert bool((result.crack_p50_m[:, -1] > now).all())
    # whole flights: every drawn value is one of the missions'
    assert set(np.unique(future.draw(1))) <= set(plan.stress_range_mpa.tolist())


def test_resampled_recent_flights_are_drawn_whole() -> None:
    walker = _model("walker", 0.6)
    recent = [[CRUISE, LOW, CRUISE], [LOW]]
    loads = resampled_spectra(walker, recent, n_flights=40, seed=3)
    draw = loads.draw(0)
    pools = [set(flight_ranges(walker, flights).tolist()) for flights in recent]
    for tail, pool in enumerate(pools):
        assert set(draw[tail].tolist()) <= pool
