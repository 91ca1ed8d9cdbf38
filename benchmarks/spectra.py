"""Load spectra against one damage-equivalent range per flight, on a fleet whose truth is
Walker's law, with an oracle.

    .venv/bin/python -m benchmarks.spectra                  # seed 0
    .venv/bin/python -m benchmarks.spectra --seeds 0 1 2

The hidden fleet (model/spectra_fleet.py): the thesis fleet's 300 tails, missions and mixes,
every flight a ground-air-ground cycle plus its mission's gust and manoeuvre cycles (up to 10
a flight, R from -0.3 to 0.7), Walker's law with gamma 0.6 as the truth, the geometry-factor
discrepancy, growth scatter exp(0.25 z), tails changing routes after 2.5 years; 100 random
tails inspected at years 2 and 4 with 4 % sizing error (as benchmarks/tracking.py), year-5
forecasts from year 4 with the true year-5 loads.  Each input is fitted the way the service's
retrain fits (model.kernel_choice.Recipe: C and m, and gamma where there are cycles, learned
from the thesis's Paris constants, then the tracked residual hybrid and its posterior):

* spectra: the recorded cycles, growth law "walker" (its gamma learned);
* single:  one range per flight, [sum n dS**m]**(1/m) with the truth's m and R ignored
           (today's input), growth law "paris";
* oracle:  the true law and prior, each tail's grid posterior (benchmarks/tracking.py).

Scores as benchmarks/tracking.py; `ratio` is a p50 median error over the oracle's.  fit_s is the
CPU-heavy part of a retrain (the recipe's fit) for each input.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from benchmarks.tracking import SAMPLES, Forecast, _model_forecast, _oracle, _scores
from model.fleet import DISCREPANCY_20PCT, FleetConfig, inspect_at
from model.integrate import LoadHistory, Observations
from model.kernel_choice import Recipe
from model.physics import ParisLaw
from model.runtime import configure_threads
from model.spectra_fleet import SpectraFleet, SpectraFleetConfig, generate_spectra_fleet
from model.tracking import SizingError, TailEvidence

INSPECTED = 100


def _fit_and_forecast(
    spectra: SpectraFleet,
    history: LoadHistory,
    future: LoadHistory,
    growth_law: str,
    obs: Observations,
    seed: int,
) -> tuple[Forecast, float, ParisLaw]:
    n = spectra.fleet.size
    evidence = TailEvidence(history, torch.arange(n), obs, n)
    recipe = Recipe(law=ParisLaw(), learn_paris=True, sizing=SizingError(), growth_law=growth_law)
    started = time.process_time()
    fitted, tracked = recipe.fit(evidence)
    fit_s = time.process_time() - started
    model = fitted.model
    future_mpa = model.loads_for(future).stress_range_mpa.numpy()
    factors = torch.exp(tracked.posterior.sample(SAMPLES, seed=seed))
    forecast = _model_forecast(model, fitted.weights, history, future_mpa, factors)
    return forecast, fit_s, model.spec.law


def run_case(seed: int, scatter: float, noise: float) -> dict[str, dict[str, float]]:
    spectra = generate_spectra_fleet(
        SpectraFleetConfig(
            FleetConfig(discrepancy=DISCREPANCY_20PCT, growth_scatter=scatter, seed=seed)
        )
    )
    fleet = spectra.fleet
    fpy = fleet.config.flights_per_year
    year4 = 4 * fpy
    rng = np.random.default_rng(seed + 100)
    chosen = np.sort(rng.choice(fleet.size, INSPECTED, replace=False))
    sample = inspect_at(fleet, chosen, np.array([2 * fpy, year4]), noise_sd=noise, seed=seed)
    local = sample.observations
    obs = Observations(
        torch.from_numpy(chosen)[local.aircraft], local.flights, local.crack_length_m
    )
    truth = fleet.crack_length_m[:, -1]
    law = spectra.law
    lengths = torch.full((fleet.size,), year4, dtype=torch.long)
    later = torch.full((fleet.size,), fleet.stress_range_mpa.shape[1] - year4, dtype=torch.long)

    cycles = spectra.cycles
    future_cycles = type(cycles)(
        cycles.stress_range_mpa[:, year4:], cycles.load_ratio[:, year4:], cycles.count[:, year4:]
    )
    inputs = {
        "spectra": (
            spectra.history(year4),
            LoadHistory.from_cycles(future_cycles, later, "walker", law.constants),
            "walker",
        ),
    }
    single = torch.from_numpy(spectra.paris_equivalent_mpa())
    inputs["single"] = (
        LoadHistory(single[:, :year4].contiguous(), lengths),
        LoadHistory(single[:, year4:].contiguous(), later),
        "paris",
    )
    forecasts: dict[str, Forecast] = {}
    extra: dict[str, dict[str, float]] = {}
    for name, (history, future, growth_law) in inputs.items():
        forecast, fit_s, fitted_law = _fit_and_forecast(
            spectra, history, future, growth_law, obs, seed
        )
        forecasts[name] = forecast
        extra[name] = {"fit_s": fit_s, "m": fitted_law.m, "gamma": fitted_law.gamma}
    forecasts["oracle"] = _oracle(fleet, year4, chosen, sample, noise, scatter)

    inspected = np.zeros(fleet.size, bool)
    inspected[chosen] = True
    below = truth < law.critical_crack_m
    groups = {
        "inspected": inspected,
        "inspected<acrit": inspected & below,
        "uninspected": ~inspected,
    }
    out: dict[str, dict[str, float]] = {}
    for name, forecast in forecasts.items():
        for group, mask in groups.items():
            scores: dict[str, float] = dict(_scores(forecast, truth, law.critical_crack_m, mask))
            oracle = _scores(forecasts["oracle"], truth, law.critical_crack_m, mask)
            scores["ratio"] = scores["p50_med_%"] / oracle["p50_med_%"]
            out[f"{name}/{group}"] = scores
        out[f"{name}/inspected"].update(extra.get(name, {}))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--scatter", type=float, default=0.25)
    parser.add_argument("--noise", type=float, default=0.04)
    args = parser.parse_args()
    configure_threads()
    for seed in args.seeds:
        print(f"## seed {seed}, scatter {args.scatter}, sizing {args.noise}", flush=True)
        for key, scores in run_case(seed, args.scatter, args.noise).items():
            shown = ", ".join(
                f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}" for k, v in scores.items()
            )
            print(f"{key:<24} {shown}", flush=True)


if __name__ == "__main__":
    main()
