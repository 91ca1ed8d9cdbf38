"""`fleetpinn fit` on long-format files (model.records), and what it shares with `predict`
(app.cli.predict): the model and law options, the tails' evidence, writing tables.  Needs no
database: nothing here imports FastAPI or SQLAlchemy.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
import torch

from app.cli.location_files import location_inspections, location_options, scaled_loads
from app.cli.progress import Bar
from app.cli.registry import CommandError, command
from model import posterior as door
from model import records
from model.growth_laws import GROWTH_LAWS
from model.materials import law_for, materials
from model.materials_file import MaterialsFileError
from model.physics import ParisLaw
from model.posterior import SizingError, TailEvidence, kernel_names
from model.spectrum_files import load_flight_records, with_cycles
from model.training_data import TrainingData, assemble

# --- fit -------------------------------------------------------------------------------------


def model_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--kernel",
        choices=kernel_names(),
        default="physics",
        help="physics: the law's dK with its geometry factor's shape learned (default, as the "
        "service's retrain); residual: dK times (1 + MLP); mlp: MLP replaces dK (thesis)",
    )
    parser.add_argument(
        "--mlp",
        type=int,
        choices=sorted(door.THESIS_MLPS),
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
        metavar="NAME",
        help="an alloy by name, of the shipped table (" + ", ".join(materials()) + ") or of "
        "--materials-file: its C, m and gamma (and NASGRO terms, where its row has them) "
        "replace the flags'",
    )
    group.add_argument(
        "--materials-file",
        type=Path,
        metavar="PATH",
        help="a CSV of the shipped table's columns (docs/api.md) whose rows add to the shipped "
        "ones and replace one of the same name: your own constants, e.g. NASGRO terms",
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
    try:
        table = materials(args.materials_file)
    except MaterialsFileError as exc:
        raise CommandError(str(exc)) from exc
    if args.material is not None and args.material not in table:
        raise CommandError(
            f"--material: unknown material {args.material!r}; known: {', '.join(table)}"
        )
    law = law if args.material is None else law_for(args.material, law, args.materials_file)
    if args.growth_law == "nasgro" and law.nasgro is None:
        raise CommandError(
            "--growth-law nasgro needs a --material whose row has NASGRO terms (the shipped "
            "table has none: bring them with --materials-file, docs/api.md)"
        )
    if args.growth_law == "nasgro" and args.learn_paris:
        raise CommandError("--learn-paris fits paris or walker, not the nasgro law")
    return law


def _fit_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--flights", type=Path, required=True, help="flights .csv or .parquet")
    parser.add_argument(
        "--inspections", type=Path, required=True, help="inspections .csv or .parquet"
    )
    parser.add_argument("--out", type=Path, required=True, help="model file to write")
    location_options(parser, "fit that location's model (its physics by the flags below)")
    model_options(parser)
    _law_options(parser)
    parser.add_argument(
        "--sizing-relative-sd",
        type=float,
        default=SizingError().relative_sd,
        metavar="SD",
        help="the inspection method's sizing error, sd of ln(measured / true) (default "
        f"{SizingError().relative_sd}; the service's location catalogue carries it per "
        "method): assumed where too few tails are measured twice to estimate it, as with one "
        "inspection a tail",
    )


def sizing_from_args(args: argparse.Namespace) -> SizingError:
    if not 0 < args.sizing_relative_sd <= 1:
        raise CommandError(
            f"--sizing-relative-sd must lie in (0, 1], got {args.sizing_relative_sd}"
        )
    return SizingError(args.sizing_relative_sd)


def read_training_data(
    flights: Path,
    inspections: Path,
    growth_law: str = "paris",
    law: ParisLaw | None = None,
    *,
    location: str | None = None,
    stress_factor: float = 1.0,
) -> TrainingData:
    """Validate both files and map each inspection to its tail's flight count: the inspections
    at `location` (app.cli.location_files), the loads times its stress_factor.  A cycle file
    (model.spectrum_files) keeps every flight's cycles in the loads, reduced under the law."""
    constants = (law or ParisLaw()).constants
    flight_table, recorded = scaled_loads(
        *load_flight_records(flights, growth_law, constants), stress_factor
    )
    tails = flight_table["tail"].unique()
    inspection_table = location_inspections(inspections, tails, location)
    data = assemble(flight_table, inspection_table, source=inspections.name)
    return data if recorded is None else with_cycles(data, recorded, growth_law, constants)


@dataclass(frozen=True)
class FittedModel:
    """What `fit` writes: the posterior (model.posterior) and its metrics."""

    posterior: door.LocationPosterior
    metrics: dict[str, Any]


def fit_recipe(
    kernel: str,
    mlp: int,
    seed: int,
    law: ParisLaw | None = None,
    learn_paris: bool = False,
    growth_law: str = "paris",
    sizing: SizingError | None = None,
) -> door.Recipe:
    """`fit`'s recipe: the model's defaults where the command takes no option (the service's
    retrain reads the same fields from its settings, app.services.jobs.retrain.service_recipe)."""
    return door.Recipe(
        kernel=kernel,
        law=law or ParisLaw(),
        hidden=door.THESIS_MLPS[mlp],
        learn_paris=learn_paris,
        sizing=sizing or SizingError(),
        config=door.TrainConfig(seed=seed),
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
    sizing: SizingError | None = None,
) -> FittedModel:
    """Fit a crack model to the inspections and measure it on them: training |% error| over
    the measured inspections (model.evaluation, as the service's retrain reports it).  The
    fleet prior of individual aircraft tracking (model.tracking_fit) is fitted too and kept in
    metrics["tracking"], so `predict --inspections` can condition each tail on its own; and the
    last layer's Laplace posterior (one mode), with each tail at its own factor, so that its
    bands carry what the inspections leave open of the shared physics too.  A learned kernel
    is kept only where it predicts held-out measurements better than the physics alone
    (model.kernel_choice; metrics["kernel"] says which).  learn_paris: fit C and m first
    (model.paris_calibration).  sizing: the inspection method's sizing error, assumed where the
    inspections cannot measure it."""
    if kernel != "physics" and len(data.observations.aircraft) == 0:
        raise CommandError("the inspections file holds no inspection to fit to")
    recipe = fit_recipe(kernel, mlp, seed, law, learn_paris, growth_law, sizing)
    with Bar("fit") as bar:
        bar.update(0.0, "fitting the model")
        fitted = door.fit(
            recipe, tail_evidence(data), progress=lambda fraction: bar.update(0.5 * fraction)
        )
        bar.update(1.0, "done")
    posterior, choice, result = fitted.posterior, fitted.choice, fitted.result
    prior, law = posterior.tracking, posterior.law
    assert prior is not None  # a fit tracks its tails
    metrics: dict[str, Any] = {
        "kernel": posterior.model.spec.kernel,
        "mlp": mlp,
        "seed": seed,
        "aircraft": len(data.tails),
        "inspections": len(data.observations.aircraft),
        "fit_seconds": round(result.seconds, 3),
    }
    errors = posterior.errors(data.loads, data.observations)
    if errors["count"]:
        metrics["train_abs_pct_error_median"] = errors["median_abs_pct_error"]
        metrics["train_abs_pct_error_max"] = errors["max_abs_pct_error"]
    metrics["growth_sd"] = round(prior.growth_sd, 4)
    metrics["tracking"] = prior.to_dict()
    metrics["paris"] = {"c": law.c, "m": law.m, "learned": learn_paris}
    metrics["growth_law"] = {"name": posterior.growth_law, "gamma": law.gamma}
    if choice:
        metrics["kernel_choice"] = choice
    return FittedModel(posterior, metrics)


def save_fitted(fitted: FittedModel, path: Path) -> None:
    _write(path, lambda: fitted.posterior.save(path, fitted.metrics))


def tail_evidence(data: TrainingData) -> TailEvidence:
    """Each tail one history (offline files carry no repairs) and its inspections."""
    tails = len(data.tails)
    return TailEvidence(data.loads, torch.arange(tails), data.observations, tails)


@command("fit", "train a crack model on flight and inspection files", _fit_arguments)
def run_fit(args: argparse.Namespace) -> int:
    law, sizing = law_from_args(args), sizing_from_args(args)
    data = read_training_data(
        args.flights,
        args.inspections,
        args.growth_law,
        law,
        location=args.location,
        stress_factor=args.stress_factor,
    )
    fitted = fit_model(
        data, args.kernel, args.mlp, args.seed, law, args.learn_paris, args.growth_law, sizing
    )
    save_fitted(fitted, args.out)
    summary = ", ".join(
        f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}"
        for k, v in fitted.metrics.items()
        if not isinstance(v, dict)
    )
    print(f"wrote {args.out} ({summary})")
    return 0


def _write(path: Path, write: Callable[[], None]) -> None:
    try:
        write()
    except OSError as exc:
        raise CommandError(f"{path.name}: cannot write: {exc.strerror or exc}") from exc


def write_table(frame: pd.DataFrame, path: Path) -> None:
    """records.write_table with a write failure reported as a CommandError."""
    _write(path, lambda: records.write_table(frame, path))
