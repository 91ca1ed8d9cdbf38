"""The offline subcommands of `fleetpinn`: fit and predict on long-format files
(model.records).  They need no database: nothing here imports FastAPI or SQLAlchemy.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch

from app.cli.progress import Bar
from app.cli.registry import CommandError, command
from app.default_location import DEFAULT_LOCATION
from model import artifacts, records
from model.evaluation import abs_percent_errors
from model.fleet_sampling import crack_samples
from model.growth_laws import GROWTH_LAWS
from model.hybrid import CrackGrowthModel, kernel_names
from model.kernel_choice import Recipe, choose_kernel
from model.materials import law_for, materials
from model.nets import THESIS_MLPS
from model.path_drift import latest_measured, wander
from model.physics import ParisLaw
from model.record_validation import load_inspections, validate_inspections
from model.spectrum_files import load_flight_records, with_cycles
from model.tracking import SizingError, TailEvidence, TrackingPrior, growth_posterior
from model.train import TrainConfig
from model.training_data import TrainingData, assemble
from model.uncertainty import LaplacePosterior

# samples of a tail's growth posterior behind predict's p05/p50/p95
PREDICT_SAMPLES = 200

# --- fit -------------------------------------------------------------------------------------


def model_options(parser: argparse.ArgumentParser) -> None:
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


def _law_options(parser: argparse.ArgumentParser) -> None:
    """The fleet's physics: Paris' law constants (SI: m, MPa; defaults the thesis's alloy)."""
    group = parser.add_argument_group("physics (Paris' law, SI units)")
    defaults = ParisLaw()
    for name, flag, text in (
        ("c", "--paris-c", "Paris C, m per flight at dK = 1 MPa sqrt(m)"),
        ("m", "--paris-m", "Paris exponent m"),
        ("geometry_factor", "--geometry-factor", "geometry factor F in dK = F dS sqrt(pi a)"),
        ("initial_crack_m", "--initial-crack-m", "crack before the first flight, m"),
        ("critical_crack_m", "--critical-crack-m", "critical crack, m"),
    ):
        default = getattr(defaults, name)
        group.add_argument(flag, type=float, default=default, help=f"{text} (default {default})")
    group.add_argument(
        "--learn-paris",
        action="store_true",
        help="fit C and m (and Walker's gamma, where flights carry cycles) to the inspections "
        "(physics first, then the network on top; model.paris_calibration): for an alloy whose "
        "constants are not known",
    )
    group.add_argument(
        "--growth-law",
        choices=tuple(GROWTH_LAWS),
        default="paris",
        help="growth law (model.growth_laws; default paris)",
    )
    group.add_argument(
        "--walker-gamma", type=float, default=1.0, help="Walker's gamma in [0, 1] (default 1)"
    )
    group.add_argument(
        "--material",
        choices=tuple(materials()),
        help="an alloy of model/data/materials.csv: its C, m and gamma replace the flags'",
    )


def law_from_args(args: argparse.Namespace) -> ParisLaw:
    try:
        law = ParisLaw(
            c=args.paris_c,
            m=args.paris_m,
            geometry_factor=args.geometry_factor,
            initial_crack_m=args.initial_crack_m,
            critical_crack_m=args.critical_crack_m,
            gamma=args.walker_gamma,
        )
    except ValueError as exc:
        raise CommandError(f"physics: {exc}") from exc
    return law if args.material is None else law_for(args.material, law)


def _fit_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--flights", type=Path, required=True, help="flights .csv or .parquet")
    parser.add_argument(
        "--inspections", type=Path, required=True, help="inspections .csv or .parquet"
    )
    parser.add_argument("--out", type=Path, required=True, help="model file to write")
    model_options(parser)
    _law_options(parser)


def read_training_data(
    flights: Path, inspections: Path, growth_law: str = "paris", law: ParisLaw | None = None
) -> TrainingData:
    """Validate both files and map each inspection to its tail's flight count.  A cycle file
    (model.spectrum_files) keeps every flight's cycles in the loads, reduced under the law."""
    constants = (law or ParisLaw()).constants
    flight_table, recorded = load_flight_records(flights, growth_law, constants)
    inspection_table = load_inspections(inspections, known_tails=flight_table["tail"].unique())
    data = assemble(flight_table, inspection_table, source=inspections.name)
    return data if recorded is None else with_cycles(data, recorded, growth_law, constants)


@dataclass(frozen=True)
class FittedModel:
    """What `fit` writes: the model, its metrics and its weights' posterior (None for the
    physics kernel)."""

    model: CrackGrowthModel
    metrics: dict[str, Any]
    posterior: LaplacePosterior | None


def fit_recipe(
    kernel: str,
    mlp: int,
    seed: int,
    law: ParisLaw | None = None,
    learn_paris: bool = False,
    growth_law: str = "paris",
) -> Recipe:
    """`fit`'s recipe: the model's defaults where the command takes no option (the service's
    retrain reads the same fields from its settings, app.services.retrain.service_recipe)."""
    return Recipe(
        kernel=kernel,
        law=law or ParisLaw(),
        hidden=THESIS_MLPS[mlp],
        learn_paris=learn_paris,
        config=TrainConfig(seed=seed),
        growth_law=growth_law,
    )


def fit_model(
    data: TrainingData,
    kernel: str,
    mlp: int,
    seed: int,
    law: ParisLaw | None = None,
    learn_paris: bool = False,
    growth_law: str = "paris",
) -> FittedModel:
    """Fit a crack model to the inspections and measure it on them: training |% error| over
    the measured inspections (model.evaluation, as the service's retrain reports it).  The
    fleet prior of individual aircraft tracking (model.tracking_fit) is fitted too and kept in
    metrics["tracking"], so `predict --inspections` can condition each tail on its own; and the
    last layer's Laplace posterior (one mode), with each tail at its own factor, so that its
    bands carry what the inspections leave open of the shared physics too.  A learned kernel
    is kept only where it predicts held-out measurements better than the physics alone
    (model.kernel_choice; metrics["kernel"] says which).  learn_paris: fit C and m first
    (model.paris_calibration)."""
    if kernel != "physics" and len(data.observations.aircraft) == 0:
        raise CommandError("the inspections file holds no inspection to fit to")
    recipe = fit_recipe(kernel, mlp, seed, law, learn_paris, growth_law)
    with Bar("fit") as bar:
        bar.update(0.0, "fitting the model")
        chosen, choice = choose_kernel(
            recipe, _evidence(data), progress=lambda fraction: bar.update(0.5 * fraction)
        )
        bar.update(1.0, "done")
    model, prior, result = chosen.fitted.model, chosen.fitted.prior, chosen.result
    law = model.spec.law
    metrics: dict[str, Any] = {
        "kernel": model.spec.kernel,
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
    metrics["paris"] = {"c": law.c, "m": law.m, "learned": learn_paris}
    metrics["growth_law"] = {"name": model.spec.growth_law, "gamma": law.gamma}
    if choice:
        metrics["kernel_choice"] = choice
    return FittedModel(model, metrics, chosen.fitted.weights)


def save_fitted(fitted: FittedModel, path: Path) -> None:
    posterior = None if fitted.posterior is None else fitted.posterior.to_dict()
    _write(path, lambda: artifacts.save(fitted.model, path, fitted.metrics, posterior))


def _evidence(data: TrainingData) -> TailEvidence:
    """Each tail one history (offline files carry no repairs) and its inspections."""
    tails = len(data.tails)
    return TailEvidence(data.loads, torch.arange(tails), data.observations, tails)


@command("fit", "train a crack model on flight and inspection files", _fit_arguments)
def run_fit(args: argparse.Namespace) -> int:
    law = law_from_args(args)
    data = read_training_data(args.flights, args.inspections, args.growth_law, law)
    fitted = fit_model(
        data, args.kernel, args.mlp, args.seed, law, args.learn_paris, args.growth_law
    )
    save_fitted(fitted, args.out)
    summary = ", ".join(
        f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}"
        for k, v in fitted.metrics.items()
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
    parser.add_argument(
        "--location",
        default=None,
        help="a control point: only the inspections whose `location` column names it (rows "
        "without one are the default location's); use the model file of that location's "
        "version (GET /models/{version}/file)",
    )
    parser.add_argument(
        "--stress-factor",
        type=float,
        default=1.0,
        help="the location's stress transfer factor: local stress per unit of the recorded one",
    )


@dataclass(frozen=True)
class LoadedModel:
    """A model file as `predict` uses it: the model, its fleet tracking prior (a file written
    before tracking: no spread, so every tail keeps the model's rate) and its weights'
    posterior (None in a file written without one)."""

    model: CrackGrowthModel
    prior: TrackingPrior
    posterior: LaplacePosterior | None


def load_model(path: Path) -> LoadedModel:
    if not path.is_file():
        raise CommandError(f"{path.name}: no such model file: {path}")
    try:
        data = path.read_bytes()
        model, metrics = artifacts.from_bytes(data)
        stored = metrics.get("tracking")
        prior = (
            TrackingPrior(0.0, SizingError()) if stored is None else TrackingPrior.from_dict(stored)
        )
        weights = artifacts.posterior_from_bytes(data)
        posterior = None if weights is None else LaplacePosterior.from_dict(weights)
    except ValueError as exc:
        raise CommandError(f"{path.name}: {exc}") from exc
    return LoadedModel(model, prior, posterior)


def predict_frame(
    loaded: LoadedModel, data: TrainingData, history: bool, conditioned: bool = False
) -> pd.DataFrame:
    """Crack length after each tail's last flight (tail, flights, crack_length_m,
    flights_to_critical: the first flight after which the crack reaches a_crit, empty where it
    does not within the file), or with `history` after every flight (plus flight_id and
    flown_at), tails in data.tails order.

    `conditioned`: each tail is conditioned on its own inspections (data.observations): the
    point values march at its posterior median growth factor, and per tail the crack's
    p05/p50/p95 (over its growth posterior and the weights' posterior, jointly sampled, and its
    path's drift since its latest measurement, model.path_variability) and the factor's are
    added."""
    model, loads = loaded.model, data.loads
    extra: dict[str, np.ndarray] = {}
    if conditioned:
        posterior = growth_posterior(model, _evidence(data), loaded.prior)
        factor_q = posterior.factor_quantiles((0.05, 0.5, 0.95)).numpy()
        loads = replace(loads, growth_factor=torch.from_numpy(factor_q[:, 1].copy()))
        cracks = crack_samples(
            model,
            loaded.posterior,
            data.loads,
            data.loads.initial_or(model.spec.law.initial_crack_m),
            samples=PREDICT_SAMPLES,
            seed=0,
            growth_factor=torch.exp(posterior.sample(PREDICT_SAMPLES, seed=0)),
        )
        median = np.quantile(cracks.numpy(), 0.5, axis=0)  # the drift moves no median
        since = latest_measured(data.loads, data.observations, model.spec.law.initial_crack_m)
        cracks = wander(cracks, since, loaded.prior.path_sd)
        crack_q = np.quantile(cracks.numpy(), (0.05, 0.5, 0.95), axis=0)
        crack_q[1] = median
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
            "flights_to_critical": _flights_to_critical(
                trajectory, lengths, model.spec.law.critical_crack_m
            ),
            **extra,
        }
    )


def _flights_to_critical(trajectory: np.ndarray, lengths: np.ndarray, critical: float) -> pd.Series:
    """First flight count k (k <= the tail's flights) with crack >= critical; <NA> if none."""
    flown = np.arange(trajectory.shape[1])[None, :] <= lengths[:, None]
    reached = (trajectory >= critical) & flown
    first = np.where(reached.any(axis=1), reached.argmax(axis=1), -1)
    return pd.Series(first, dtype="Int64").mask(first < 0)


def _write(path: Path, write: Callable[[], None]) -> None:
    try:
        write()
    except OSError as exc:
        raise CommandError(f"{path.name}: cannot write: {exc.strerror or exc}") from exc


def write_table(frame: pd.DataFrame, path: Path) -> None:
    """records.write_table with a write failure reported as a CommandError."""
    _write(path, lambda: records.write_table(frame, path))


def _location_inspections(path: Path, flights: pd.DataFrame, location: str | None) -> pd.DataFrame:
    """The file's inspections of `location` (None: all of them), validated."""
    if location is None:
        return load_inspections(path, known_tails=flights["tail"].unique())
    raw = records.read_table(path)
    given = raw["location"] if "location" in raw.columns else pd.Series("", index=raw.index)
    named = given.fillna("").astype(str).str.strip()
    named = named.where(named != "", DEFAULT_LOCATION)  # a blank cell: the default location
    mine = raw[(named == location).to_numpy()].reset_index(drop=True)
    if mine.empty:
        raise CommandError(f"{path.name}: no inspection at location {location!r}")
    return validate_inspections(mine, path.name, flights["tail"].unique())


@command("predict", "predict crack lengths for a flights file", _predict_arguments)
def run_predict(args: argparse.Namespace) -> int:
    if args.out.suffix.lower() not in (".csv", ".parquet"):
        raise CommandError(
            f"{args.out.name}: unknown file type {args.out.suffix!r}; use .csv or .parquet"
        )
    if not args.stress_factor > 0:
        raise CommandError(f"--stress-factor must be > 0, got {args.stress_factor}")
    loaded = load_model(args.model)
    spec = loaded.model.spec
    flights, recorded = load_flight_records(args.flights, spec.growth_law, spec.law.constants)
    if args.stress_factor != 1.0:  # the loads as the location sees them (R unchanged)
        flights = flights.assign(stress_range_mpa=flights["stress_range_mpa"] * args.stress_factor)
        if recorded is not None:
            recorded = {
                key: replace(cycles, stress_range_mpa=cycles.stress_range_mpa * args.stress_factor)
                for key, cycles in recorded.items()
            }

    def with_recorded(data: TrainingData) -> TrainingData:
        if recorded is None:
            return data
        return with_cycles(data, recorded, spec.growth_law, spec.law.constants)

    if args.inspections is None:
        frame = predict_frame(loaded, with_recorded(assemble(flights)), args.history)
        data_tails = flights["tail"].nunique()
    else:
        inspections = _location_inspections(args.inspections, flights, args.location)
        data = with_recorded(assemble(flights, inspections, source=args.inspections.name))
        frame = predict_frame(loaded, data, args.history, conditioned=True)
        data_tails = len(data.tails)
    write_table(frame, args.out)
    print(f"wrote {args.out} ({len(frame)} rows, {data_tails} tails)")
    return 0
