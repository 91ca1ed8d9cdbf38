"""`fleetpinn demo`: a synthetic thesis fleet written to files, fitted on an inspection sample
through the same path as `fit`, and scored against its truth.  The fleet's options are shared
with the service's `seed-demo`.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from app.cli.offline import fit_model, model_options, read_training_data, save_fitted, write_table
from app.cli.registry import CommandError, command
from model.fleet import (
    DISCREPANCY_20PCT,
    SELECTIONS,
    FleetConfig,
    generate_fleet,
    scheduled_inspection,
)
from model.posterior import physics_alone

# --- demo ------------------------------------------------------------------------------------


def fleet_arguments(parser: argparse.ArgumentParser) -> None:
    """The synthetic thesis fleet's options (model.fleet), shared by `demo` and `seed-demo`."""
    parser.add_argument(
        "--inspected", type=int, default=15, help="aircraft inspected at the end (default 15)"
    )
    parser.add_argument(
        "--aircraft-per-mix", type=int, default=100, help="fleet size / 3 (default 100)"
    )
    parser.add_argument("--years", type=int, default=5, help="years flown (default 5)")
    parser.add_argument(
        "--discrepancy",
        type=float,
        default=DISCREPANCY_20PCT,
        help="beta of the truth's geometry factor F(a) the physics lacks (default "
        f"{DISCREPANCY_20PCT}: physics alone errs up to ~20 %%; 0 = plain Paris law)",
    )


def _demo_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--out-dir", type=Path, default=Path("demo"), help="where to write files (default demo/)"
    )
    fleet_arguments(parser)
    parser.add_argument(
        "--selection",
        default="uniform-coverage",
        choices=SELECTIONS,
        help="which aircraft are inspected (default uniform-coverage)",
    )
    model_options(parser)
    # the demonstration is the thesis's: a network learning the physics the law lacks
    parser.set_defaults(kernel="residual")


def _error_summary(predicted: np.ndarray, truth: np.ndarray) -> str:
    error = np.abs(predicted / truth - 1.0) * 100
    p50, p95 = np.percentile(error, [50, 95])
    return f"median {p50:.2f} %, p95 {p95:.2f} %, max {error.max():.2f} %"


@command(
    "demo",
    "synthetic thesis fleet: write its files, fit on an inspection sample, score the fleet",
    _demo_arguments,
)
def run_demo(args: argparse.Namespace) -> int:

    try:
        config = FleetConfig(
            aircraft_per_mix=args.aircraft_per_mix,
            years=args.years,
            discrepancy=args.discrepancy,
            seed=args.seed,
        )
        fleet = generate_fleet(config)
        sample = scheduled_inspection(fleet, args.inspected, args.selection, seed=args.seed)
    except ValueError as exc:
        raise CommandError(str(exc)) from exc
    args.out_dir.mkdir(parents=True, exist_ok=True)
    flights_path = args.out_dir / "flights.csv"
    inspections_path = args.out_dir / "inspections.csv"
    started = time.perf_counter()
    write_table(fleet.flights_frame(), flights_path)
    write_table(fleet.inspections_frame(sample), inspections_path)
    print(
        f"wrote {flights_path} ({fleet.size} aircraft x {config.flights} flights) and "
        f"{inspections_path} ({args.inspected} {args.selection}) "
        f"in {time.perf_counter() - started:.1f} s"
    )

    started = time.perf_counter()
    data = read_training_data(flights_path, inspections_path)
    read_seconds = time.perf_counter() - started
    fitted = fit_model(data, args.kernel, args.mlp, args.seed)
    posterior, metrics = fitted.posterior, fitted.metrics
    model_path = args.out_dir / "model.pt"
    save_fitted(fitted, model_path)
    print(
        f"read + validated in {read_seconds:.1f} s; fit {args.kernel} (MLP #{args.mlp}) "
        f"in {metrics['fit_seconds']} s -> {model_path}"
    )

    truth = pd.Series(fleet.final_crack_m, index=fleet.tails)[data.tails].to_numpy()
    predicted = posterior.final_crack(data.loads).numpy()
    physics = physics_alone().final_crack(data.loads).numpy()
    print(f"year-{args.years} |% error| over {len(truth)} aircraft:")
    print(f"  {'fitted ' + args.kernel:<16} {_error_summary(predicted, truth)}")
    print(f"  {'physics alone':<16} {_error_summary(physics, truth)}")
    return 0
