"""The offline subcommands of `fleetpinn`: fit, predict and demo on long-format files
(model.records).  They need no database: nothing here imports FastAPI or SQLAlchemy.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch

from app.cli.progress import Bar
from app.cli.registry import CommandError, command
from model import artifacts, records
from model.evaluation import abs_percent_errors
from model.fleet import (
    DISCREPANCY_20PCT,
    SELECTIONS,
    FleetConfig,
    generate_fleet,
    scheduled_inspection,
)
from model.fleet_sampling import crack_samples
from model.hybrid import CrackGrowthModel, ModelSpec, kernel_names
from model.nets import THESIS_MLPS
from model.record_validation import load_flights, load_inspections
from model.tracking import SizingError, TailEvidence, TrackingPrior, growth_posterior
from model.tracking_fit import fit_tracked
from model.train import FitResult, TrainConfig, build_crack_model
from model.training_data import TrainingData, assemble

# samples of a tail's growth posterior behind predict's p05/p50/p95
PREDICT_SAMPLES = 200

# --- fit -------------------------------------------------------------------------------------


def _model_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--kernel",
        choices=kernel_names(),
        default="residual",
        help="residual: Paris dK times (1 + MLP) (default); mlp: MLP replaces dK (thesis); "
        "physics: Paris law alone, nothing to fit",
    )
    parser.add_argument(
        "--mlp",
        type=int,
        choices=sorted(THESIS_MLPS),
        default=1,
        help="thesis MLP design 1..7 (Table 4.4; default 1: Dense(5, tanh))",
    )
    parser.add_argument("--seed", type=int, default=0, help="random seed of the fit (default 0)")


def _fit_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--flights", type=Path, required=True, help="flights .csv or .parquet")
    parser.add_argument(
        "--inspections", type=Path, required=True, help="inspections .csv or .parquet"
    )
    parser.add_argument("--out", type=Path, required=True, help="model file to write")
    _model_options(parser)


def read_training_data(flights: Path, inspections: Path) -> TrainingData:
    """Validate both files and map each inspection to its tail's flight count."""
    flight_table = load_flights(flights)
    inspection_table = load_inspections(inspections, known_tails=flight_table["tail"].unique())
    return assemble(flight_table, inspection_table, source=inspections.name)


def fit_model(
    data: TrainingData, kernel: str, mlp: int, seed: int
) -> tuple[CrackGrowthModel, FitResult, dict[str, Any]]:
    """Fit a crack model to the inspections and measure it on them: training |% error| over
    the measured inspections (model.evaluation, as the service's retrain reports it).  The
    fleet prior of individual aircraft tracking (model.tracking_fit) is fitted too and kept in
    metrics["tracking"], so `predict --inspections` can condition each tail on its own."""
    if kernel != "physics" and len(data.observations.aircraft) == 0:
        raise CommandError("the inspections file holds no inspection to fit to")
    with Bar("fit") as bar:
        bar.update(0.0, "fitting the model")
        model = build_crack_model(data.loads, kernel=kernel, hidden=THESIS_MLPS[mlp], seed=seed)
        tracked = fit_tracked(
            model,
            _evidence(data),
            SizingError(),
            TrainConfig(seed=seed),
            progress=lambda fraction: bar.update(0.95 * fraction),
        )
        prior, result = tracked.prior, tracked.result
        bar.update(1.0, "done")
    metrics: dict[str, Any] = {
        "kernel": kernel,
        "mlp": mlp,
        "seed": seed,
        "aircraft": len(data.tails),
        "inspections": len(data.observations.aircraft),
        "fit_seconds": round(result.seconds, 3),
    }
    errors = abs_percent_errors(model, data.loads, data.observations)
    if errors["count"]:
        metrics["train_abs_pct_error_median"] = errors["median_abs_pct_error"]
        metrics["train_abs_pct_error_max"] = errors["max_abs_pct_error"]
    metrics["growth_sd"] = round(prior.growth_sd, 4)
    metrics["tracking"] = prior.to_dict()
    return model, result, metrics


def _evidence(data: TrainingData) -> TailEvidence:
    """Each tail one history (offline files carry no repairs) and its inspections."""
    tails = len(data.tails)
    return TailEvidence(data.loads, torch.arange(tails), data.observations, tails)


@command("fit", "train a crack model on flight and inspection files", _fit_arguments)
def run_fit(args: argparse.Namespace) -> int:
    data = read_training_data(args.flights, args.inspections)
    model, _, metrics = fit_model(data, args.kernel, args.mlp, args.seed)
    _write(args.out, lambda: artifacts.save(model, args.out, metrics))
    summary = ", ".join(
        f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}"
        for k, v in metrics.items()
        if not isinstance(v, dict)
    )
    print(f"wrote {args.out} ({summary})")
    return 0


# --- predict ---------------------------------------------------------------------------------


def _predict_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--model", type=Path, required=True, help="model file from `fit`")
    parser.add_argument("--flights", type=Path, required=True, help="flights .csv or .parquet")
    parser.add_argument("--out", type=Path, required=True, help="predictions .csv or .parquet")
    parser.add_argument(
        "--inspections",
        type=Path,
        help="inspections .csv or .parquet: each tail is conditioned on its own (its growth "
        "posterior, model.tracking) and p05/p50/p95 are written",
    )
    parser.add_argument(
        "--history",
        action="store_true",
        help="one row per flight (the crack after it) instead of one per tail",
    )


def load_model(path: Path) -> tuple[CrackGrowthModel, TrackingPrior]:
    """The model and its fleet tracking prior (a file written before tracking: no spread, so
    every tail keeps the model's rate)."""
    if not path.is_file():
        raise CommandError(f"{path.name}: no such model file: {path}")
    try:
        model, metrics = artifacts.load(path)
        stored = metrics.get("tracking")
        prior = (
            TrackingPrior(0.0, SizingError()) if stored is None else TrackingPrior.from_dict(stored)
        )
    except ValueError as exc:
        raise CommandError(f"{path.name}: {exc}") from exc
    return model, prior


def predict_frame(
    model: CrackGrowthModel,
    data: TrainingData,
    history: bool,
    prior: TrackingPrior | None = None,
) -> pd.DataFrame:
    """Crack length after each tail's last flight (tail, flights, crack_length_m), or with
    `history` after every flight (plus flight_id and flown_at), tails in data.tails order.

    With a tracking prior each tail is conditioned on its own inspections (data.observations):
    the point values march at its posterior median growth factor, and per tail the crack's
    p05/p50/p95 and the factor's are added (sampled over the tail's growth posterior)."""
    loads = data.loads
    extra: dict[str, np.ndarray] = {}
    if prior is not None:
        posterior = growth_posterior(model, _evidence(data), prior)
        factor_q = posterior.factor_quantiles((0.05, 0.5, 0.95)).numpy()
        loads = replace(loads, growth_factor=torch.from_numpy(factor_q[:, 1].copy()))
        cracks = crack_samples(
            model,
            None,
            data.loads,
            data.loads.initial_or(model.spec.law.initial_crack_m),
            samples=PREDICT_SAMPLES,
            seed=0,
            growth_factor=torch.exp(posterior.sample(PREDICT_SAMPLES, seed=0)),
        ).numpy()
        crack_q = np.quantile(cracks, (0.05, 0.5, 0.95), axis=0)
        extra = {
            "crack_p05_m": crack_q[0],
            "crack_p50_m": crack_q[1],
            "crack_p95_m": crack_q[2],
            "growth_factor_p05": factor_q[:, 0],
            "growth_factor_p50": factor_q[:, 1],
            "growth_factor_p95": factor_q[:, 2],
        }
    with torch.no_grad():
        trajectory = model.trajectory(loads).numpy()  # (aircraft, flights + 1)
    if history:
        ordered = data.flights
        aircraft, position = ordered["aircraft"].to_numpy(), ordered["flight"].to_numpy()
        return pd.DataFrame(
            {
                "tail": ordered["tail"].to_numpy(),
                "flights": position,
                "crack_length_m": trajectory[aircraft, position],
                "flight_id": ordered["flight_id"].to_numpy(),
                "flown_at": ordered["flown_at"].array,
            }
        )
    lengths = data.loads.lengths.numpy()
    return pd.DataFrame(
        {
            "tail": data.tails,
            "flights": lengths,
            "crack_length_m": trajectory[np.arange(len(lengths)), lengths],
            **extra,
        }
    )


def _write(path: Path, write: Callable[[], None]) -> None:
    try:
        write()
    except OSError as exc:
        raise CommandError(f"{path.name}: cannot write: {exc.strerror or exc}") from exc


def write_table(frame: pd.DataFrame, path: Path) -> None:
    """records.write_table with a write failure reported as a CommandError."""
    _write(path, lambda: records.write_table(frame, path))


@command("predict", "predict crack lengths for a flights file", _predict_arguments)
def run_predict(args: argparse.Namespace) -> int:
    if args.out.suffix.lower() not in (".csv", ".parquet"):
        raise CommandError(
            f"{args.out.name}: unknown file type {args.out.suffix!r}; use .csv or .parquet"
        )
    model, prior = load_model(args.model)
    flights = load_flights(args.flights)
    if args.inspections is None:
        frame = predict_frame(model, assemble(flights), args.history)
        data_tails = flights["tail"].nunique()
    else:
        inspections = load_inspections(args.inspections, known_tails=flights["tail"].unique())
        data = assemble(flights, inspections, source=args.inspections.name)
        frame = predict_frame(model, data, args.history, prior)
        data_tails = len(data.tails)
    write_table(frame, args.out)
    print(f"wrote {args.out} ({len(frame)} rows, {data_tails} tails)")
    return 0


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
    _model_options(parser)


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
    model, _, metrics = fit_model(data, args.kernel, args.mlp, args.seed)
    model_path = args.out_dir / "model.pt"
    _write(model_path, lambda: artifacts.save(model, model_path, metrics))
    print(
        f"read + validated in {read_seconds:.1f} s; fit {args.kernel} (MLP #{args.mlp}) "
        f"in {metrics['fit_seconds']} s -> {model_path}"
    )

    truth = pd.Series(fleet.final_crack_m, index=fleet.tails)[data.tails].to_numpy()
    with torch.no_grad():
        fitted = model.final_crack(data.loads).numpy()
        physics = CrackGrowthModel(ModelSpec(kernel="physics")).final_crack(data.loads).numpy()
    print(f"year-{args.years} |% error| over {len(truth)} aircraft:")
    print(f"  {'fitted ' + args.kernel:<16} {_error_summary(fitted, truth)}")
    print(f"  {'physics alone':<16} {_error_summary(physics, truth)}")
    return 0
