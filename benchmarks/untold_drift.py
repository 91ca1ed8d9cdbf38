"""Which drift a forecast carries where nothing can be held out to measure it and tails scatter.

    .venv/bin/python -m benchmarks.untold_drift --cases secant-once flat-once --seeds 1 2
    .venv/bin/python -m benchmarks.untold_drift --drifts 0 0.25 0.5 1   # the candidates

Where each tail is measured once and tails scatter, model.kernel_choice keeps the physics (its
shape over crack length cannot be checked) and no later measurement says how far forecasts
drift, so the drift (path_sd) is a prior, UNTOLD_PATH_SD.  Here it is chosen: each case of
benchmarks/extrapolation.py is fitted once as the service's retrain fits it (choose_kernel), and
its tails' year-5 cracks are forecast from year 4 under each candidate drift (the fit does not
depend on it), scored as extrapolation.py scores them, inspected and uninspected tails apart,
beside the oracle (true physics and spread, each tail's grid posterior).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from benchmarks.extrapolation import CASES, SAMPLES, SHOWN, inspected_fleet, year4_evidence
from benchmarks.tracking import Forecast, _model_forecast, _oracle, _scores
from model.kernel_choice import UNTOLD_PATH_SD, Recipe, choose_kernel
from model.path_drift import PathDrift, latest_measured
from model.runtime import configure_threads


def run_case(name: str, seed: int, drifts: list[float]) -> None:
    """Print the case's oracle and model rows, one model row per drift."""
    case = CASES[name]
    started = time.perf_counter()
    fleet, chosen, sample = inspected_fleet(case, seed)
    year4 = 4 * fleet.config.flights_per_year
    history, fleet_obs, evidence = year4_evidence(fleet, chosen, sample)
    truth, law = fleet.crack_length_m[:, -1], fleet.config.law
    torch.manual_seed(seed)
    model, choice = choose_kernel(Recipe(law=law), evidence)
    fitted = model.fitted
    spec = fitted.model.spec
    print(
        f"## {name} seed {seed}: kernel {choice.get('chosen', spec.kernel)}, drift measured: "
        f"{model.path.held_out_log_likelihood is not None}, growth sd "
        f"{fitted.prior.growth_sd:.3f}, fit {time.perf_counter() - started:.0f} s",
        flush=True,
    )
    inspected = np.zeros(fleet.size, bool)
    inspected[chosen] = True
    groups = {"inspected": inspected, "uninspected": ~inspected}

    def show(label: str, forecast: Forecast) -> None:
        for group, mask in groups.items():
            scores = _scores(forecast, truth, law.critical_crack_m, mask)
            shown = ", ".join(f"{k} {scores[k]:.3g}" for k in SHOWN)
            print(f"  {label:<12} {group:<12} {shown}", flush=True)

    if case.scatter > 0:
        show("oracle", _oracle(fleet, year4, chosen, sample, case.noise, case.scatter))
    factors = torch.exp(model.tracked.posterior.sample(SAMPLES, seed=seed))
    since = latest_measured(history, fleet_obs, law.initial_crack_m, spec.measured_up_to_m)
    future = fleet.stress_range_mpa[:, year4:]
    for drift_sd in drifts:
        drift = PathDrift.drawn(drift_sd, since, SAMPLES, list(range(fleet.size)))
        forecast = _model_forecast(
            fitted.model, fitted.weights, history, future, factors, drift if drift_sd else None
        )
        show(f"drift {drift_sd:g}", forecast)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    once = ["secant-once", "flat-once", "falloff-once", "secant-early", "flat-early"]
    parser.add_argument("--cases", nargs="+", default=once, choices=list(CASES))
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--drifts", type=float, nargs="+", default=[0.0, UNTOLD_PATH_SD])
    args = parser.parse_args()
    configure_threads()
    for name in args.cases:
        for seed in args.seeds:
            run_case(name, seed, args.drifts)


if __name__ == "__main__":
    main()
