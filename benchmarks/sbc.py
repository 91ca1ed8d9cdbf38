"""Calibration by simulation: fleets drawn from one declared prior, fitted and forecast through
the model's door (model.posterior), scored as a whole.

    .venv/bin/python -m benchmarks.sbc --fleets 50 --workers 2
    .venv/bin/python -m benchmarks.sbc --fleets 8 --aircraft-per-mix 10 --json out.json
    .venv/bin/python -m benchmarks.sbc --rescore out.json   (the scores again, by protocol too)

Why.  The named cases of benchmarks/extrapolation.py are a handful of fleets; a model tuned to
pass them can stay miscalibrated everywhere else.  Here each fleet is one draw of FleetPrior
(every unknown the model must learn, and the protocol that inspects it), and the scores pool
every tail of every fleet: a model whose own priors and likelihood are those of FleetPrior
must come back calibrated, whatever the draw.

FleetPrior (one place; a model's priors should say the same):
  - the truth's geometry factor shape, each a sixth: a linear rise (beta ~ U(0, 0.25)), a
    finite-width secant accelerating towards an edge (half width W ~ U(0.05, 0.12) m), a
    constant the physics misses (beta ~ U(0, 0.10)), a fall back to 1 beyond a rise
    (beta ~ U(0, 0.20)), a linear fall (beta ~ U(0, 0.20)), and a shape drawn from the
    model's own prior of the factor's departure (model.geometry_posterior.ShapePosterior.prior
    at the default slope sd: its amplitude, then its slopes); `--shapes` picks a subset (the
    first four are the FleetPrior of session 25, whose shapes never fall below the law's);
  - the tails' spread of growth rate and the sizing error, by `--noise`: "model" (the default)
    draws them from the model's own priors, tau ~ |N(0, SPREAD_PRIOR_SD)| and the relative
    sizing sd = 5 % x exp(N(0, SIZING_PRIOR_SD)) about the default 5 % the fit assumes (as a
    user who declares nothing); "uniform" is session 26's draw, tau = 0 with probability 0.3,
    else U(0.05, 0.35), and sizing sd ~ U(0.01, 0.10), which is not the model's prior (16 % of
    the sizing prior's mass lies above 10 %); the geometry and protocol draws are the same
    under both;
  - the protocol: one round at year 1, one at year 4, rounds at 2 and 4, rounds at 1 and 3, or
    a sparse round (a quarter of the tails) at year 4; a share of the tails U(0.15, 0.5) is
    inspected (at least 5), the others never.
Loads, law and a_crit are model.fleet's (the thesis fleet: four missions, 4 flights a day).
Data end at year 4; every tail is forecast 365 days ahead over its true future loads.

Scores, each for inspected tails, tails never inspected and tails forecast beyond the measured
cracks ("beyond": the forecast's year-5 p50 past the longest crack measured in their fleet).
A calibration group is chosen by what is known when the forecast is made: chosen by the outcome
(the true year-5 crack past the longest measured, "beyond_truth", the group of sessions 25-30)
it holds the tails that grew more than forecast, and a calibrated forecast then reads low in it
(tests/benchmarks/test_sbc_scores.py); it is printed beside the others as that diagnostic:
  cov90     share of year-5 cracks inside [p05, p95]                    goal 0.87-0.93
  above95   share above p95                                             (goal <= ~0.05)
  pit_p     chi-square p of the year-5 crack's bin among the predictive's
            (p05, p50, p95) bins against (5, 45, 45, 5) %               goal >= 0.01
  pit_p_fleets  the same with the statistic divided by the bins' design effect (Rao and
            Scott's correction): a fleet's tails share its fit's errors, so they are not
            independent draws (benchmarks/sbc_scores.py)                 goal >= 0.01
  z_pit_p   the same of each inspected tail's true ln growth factor among its posterior
            draws, the truth's as the model defines it: its rate against the law with the
            shape's correction, which is 1 at a0 (g(0) = 0), so the truth's own factor at a0
            (m ln(F_true(a0) / F_law(a0)), a flat discrepancy's whole size) is the fleet's
            rate's and its tails' truths carry it
and a reliability table of P(critical) by deciles (bins of >= 20 tails: |P - observed| <= 0.1).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from benchmarks.sbc_scores import print_scores, scores
from model import posterior as door
from model.extrapolation import DEFAULT_SLOPE_SD
from model.fleet import FleetConfig, generate_fleet, inspect_at, true_geometry_factor
from model.fleet_spread import SPREAD_PRIOR_SD
from model.forecast import FixedLoads
from model.geometry import GeometryTable
from model.geometry_posterior import ShapePosterior, basis, life_position
from model.integrate import LoadHistory, Observations
from model.physics import ParisLaw
from model.runtime import configure_threads
from model.tracking import SIZING_PRIOR_SD, SizingError

SAMPLES = 200
HORIZON_DAYS = 365
SHAPES = ("linear", "secant", "flat", "falloff", "fall", "prior")
PROTOCOLS: dict[str, tuple[int, ...]] = {
    "year1": (1,),
    "year4": (4,),
    "years2-4": (2, 4),
    "years1-3": (1, 3),
    "sparse4": (4,),
}
NOISES = ("model", "uniform")


@dataclass(frozen=True)
class FleetDraw:
    """One draw of FleetPrior (module docstring)."""

    seed: int
    geometry: str
    discrepancy: float
    growth_sd: float
    sizing_sd: float
    protocol: str
    inspected_share: float


def draw_fleet(seed: int, shapes: tuple[str, ...] = SHAPES, noise: str = "model") -> FleetDraw:
    """FleetPrior's draw `seed` (module docstring) over the geometry shapes `shapes`, its spread
    and sizing error by `noise` (NOISES) from a stream of their own, so that geometry and
    protocol are the same draw under both."""
    rng = np.random.default_rng([seed, 39])
    geometry = shapes[int(rng.integers(len(shapes)))]
    discrepancy = {
        "linear": lambda: rng.uniform(0.0, 0.25),
        "secant": lambda: rng.uniform(0.05, 0.12),
        "flat": lambda: rng.uniform(0.0, 0.10),
        "falloff": lambda: rng.uniform(0.0, 0.20),
        "fall": lambda: rng.uniform(0.0, 0.20),
        "prior": lambda: 0.0,  # the shape is drawn from the draw's seed (true_shape)
    }[geometry]()
    growth_sd = 0.0 if rng.uniform() < 0.3 else rng.uniform(0.05, 0.35)
    protocol = list(PROTOCOLS)[int(rng.integers(len(PROTOCOLS)))]
    share = 0.25 if protocol == "sparse4" else rng.uniform(0.15, 0.5)
    sizing_sd = rng.uniform(0.01, 0.10)
    if noise == "model":
        own = np.random.default_rng([seed, 42])
        growth_sd = abs(own.normal(0.0, SPREAD_PRIOR_SD))
        sizing_sd = SizingError().relative_sd * math.exp(own.normal(0.0, SIZING_PRIOR_SD))
    return FleetDraw(
        seed,
        geometry,
        float(discrepancy),
        float(growth_sd),
        float(sizing_sd),
        protocol,
        float(share),
    )


def true_shape(draw: FleetDraw, law: ParisLaw) -> str | GeometryTable:
    """The draw's geometry: its named shape, or for "prior" a table of F = exp(g) over [a0,
    a_crit] with g drawn from the model's own prior (an amplitude by its prior weight, then
    the slopes at the knots)."""
    if draw.geometry != "prior":
        return draw.geometry
    rng = np.random.default_rng([draw.seed, 41])
    prior = ShapePosterior.prior(law, DEFAULT_SLOPE_SD)
    k = int(rng.choice(len(prior.weights), p=np.asarray(prior.weights)))
    slopes = rng.multivariate_normal(np.asarray(prior.means[k]), np.asarray(prior.covariances[k]))
    cracks = np.linspace(law.initial_crack_m, law.critical_crack_m, 33)
    shape = basis(life_position(law, cracks)) @ slopes
    return GeometryTable.of(cracks.tolist(), np.exp(shape).tolist())


def run_fleet(draw: FleetDraw, aircraft_per_mix: int, kernel: str = "physics") -> dict[str, Any]:
    """Fit one drawn fleet through the door (the recipe's `kernel`) and read each tail's year-5
    forecast."""
    configure_threads(1)
    fleet = generate_fleet(
        FleetConfig(
            aircraft_per_mix=aircraft_per_mix,
            geometry=true_shape(draw, ParisLaw()),
            discrepancy=draw.discrepancy,
            growth_scatter=draw.growth_sd,
            seed=draw.seed,
        )
    )
    n, fpy = fleet.size, fleet.config.flights_per_year
    law = fleet.config.law
    rng = np.random.default_rng([draw.seed, 40])
    count = max(5, round(draw.inspected_share * n))
    chosen = np.sort(rng.choice(n, count, replace=False))
    times = np.array([y * fpy for y in PROTOCOLS[draw.protocol]])
    sample = inspect_at(fleet, chosen, times, noise_sd=draw.sizing_sd, seed=draw.seed)
    year4 = 4 * fpy
    stress = torch.from_numpy(fleet.stress_range_mpa)
    history = LoadHistory(stress[:, :year4].contiguous(), torch.full((n,), year4))
    obs = sample.observations
    fleet_obs = Observations(
        torch.from_numpy(chosen)[obs.aircraft], obs.flights, obs.crack_length_m
    )
    evidence = door.TailEvidence(history, torch.arange(n), fleet_obs, n)

    started = time.perf_counter()
    torch.manual_seed(draw.seed)
    fitted = door.fit(door.Recipe(kernel=kernel, law=law), evidence)
    posterior = fitted.posterior
    growth = posterior.tail_growth(posterior.update(evidence), SAMPLES, range(n))
    crack_now = posterior.crack_now(
        history,
        history.initial_or(law.initial_crack_m),
        samples=SAMPLES,
        seed=draw.seed,
        log_growth=growth.samples,
    )
    future = fleet.stress_range_mpa[:, year4 : year4 + HORIZON_DAYS * fleet.config.flights_per_day]
    risks = posterior.risk(
        crack_now.numpy(),
        [FixedLoads(future[i : i + 1]) for i in range(n)],
        [float(fleet.config.flights_per_day)] * n,
        HORIZON_DAYS,
        samples=SAMPLES,
        seed=draw.seed,
        bands=False,
        growth_factor=torch.exp(growth.samples).numpy(),
        marks=[[HORIZON_DAYS]] * n,
        drift_from_m=posterior.drift_origins(history, fleet_obs).tolist(),
        tail_seeds=list(range(n)),
        detectable_crack_m=None,
    )
    seconds = time.perf_counter() - started
    truth = fleet.crack_length_m[:, year4 + future.shape[1]]
    measured = obs.crack_length_m[obs.crack_length_m < law.critical_crack_m]
    longest = float(measured.max()) if len(measured) else law.initial_crack_m
    inspected = np.zeros(n, bool)
    inspected[chosen] = True
    at_start = true_geometry_factor(
        np.array([law.initial_crack_m]), law, fleet.config.geometry, draw.discrepancy
    )[0]
    true_z = np.log(fleet.growth_factor) + law.m * math.log(at_start / law.geometry_factor)
    z_rank = (growth.samples.numpy() < true_z[None, :]).mean(axis=0)
    q = np.array([r.marks_m[:, 0] for r in risks])  # (tails, 3): p05, p50, p95
    return {
        "draw": asdict(draw),
        "fit_s": seconds,
        "kernel": fitted.choice.get("chosen", posterior.model.spec.kernel),
        "growth_sd": posterior.tracking.growth_sd if posterior.tracking else None,
        "critical_m": law.critical_crack_m,
        "truth_m": truth.tolist(),
        "q_m": q.tolist(),
        "prob_critical": [r.prob_critical for r in risks],
        "inspected": inspected.tolist(),
        "beyond": (q[:, 1] > longest).tolist(),
        "beyond_truth": (truth > longest).tolist(),
        "z_rank": z_rank.tolist(),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--fleets", type=int, default=50)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--aircraft-per-mix", type=int, default=20, help="tails = 3 x this")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--json", type=Path, help="write every fleet's result and the scores")
    parser.add_argument("--kernel", default="physics", help="the recipe's kernel (default physics)")
    parser.add_argument(
        "--shapes", default=",".join(SHAPES), help="the geometry shapes drawn (comma-separated)"
    )
    parser.add_argument(
        "--noise", choices=NOISES, default="model", help="the spread and sizing draws (docstring)"
    )
    parser.add_argument("--rescore", type=Path, help="print the scores of a --json file, no fits")
    args = parser.parse_args()
    if args.rescore:
        results = json.loads(args.rescore.read_text())["fleets"]
        print_scores(scores(results), results)
        return
    shapes = tuple(args.shapes.split(","))
    if unknown := set(shapes) - set(SHAPES):
        parser.error(f"--shapes: unknown {sorted(unknown)}; choose from {SHAPES}")
    draws = [draw_fleet(args.first_seed + k, shapes, args.noise) for k in range(args.fleets)]
    if args.workers > 1:
        with ProcessPoolExecutor(args.workers) as pool:
            sizes, kernels = [args.aircraft_per_mix] * len(draws), [args.kernel] * len(draws)
            results = list(pool.map(run_fleet, draws, sizes, kernels))
    else:
        results = [run_fleet(d, args.aircraft_per_mix, args.kernel) for d in draws]
    summary = scores(results)
    print_scores(summary, results)
    if args.json:
        args.json.write_text(json.dumps({"scores": summary, "fleets": results}, indent=1))


if __name__ == "__main__":
    main()
