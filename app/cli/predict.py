"""`fleetpinn predict`: crack lengths for a flights file from a model file, each tail
conditioned on its own inspections where they are given.  Needs no database: nothing here
imports FastAPI or SQLAlchemy.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from app.cli.location_files import location_inspections, location_options, scaled_loads
from app.cli.offline import tail_evidence, write_table
from app.cli.registry import CommandError, command
from model.posterior import LocationPosterior, SizingError, TrackingPrior
from model.spectrum_files import load_flight_records, with_cycles
from model.training_data import TrainingData, assemble

# samples of a tail's growth posterior behind predict's p05/p50/p95
PREDICT_SAMPLES = 200


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
    location_options(
        parser, "use the model file of that location's version (GET /models/{version}/file)"
    )


def load_model(path: Path) -> LocationPosterior:
    """A model file as `predict` uses it; a file written before tracking gets no spread, so
    every tail keeps the model's rate."""
    if not path.is_file():
        raise CommandError(f"{path.name}: no such model file: {path}")
    try:
        loaded = LocationPosterior.from_bytes(path.read_bytes())
    except ValueError as exc:
        raise CommandError(f"{path.name}: {exc}") from exc
    if loaded.tracking is None:
        return replace(loaded, tracking=TrackingPrior(0.0, SizingError()))
    return loaded


def predict_frame(
    loaded: LocationPosterior, data: TrainingData, history: bool, conditioned: bool = False
) -> pd.DataFrame:
    """Crack length after each tail's last flight (tail, flights, crack_length_m,
    flights_to_critical: the first flight after which the crack reaches a_crit, empty where it
    does not within the file), or with `history` after every flight (plus flight_id and
    flown_at), tails in data.tails order.  The point values march at each tail's growth
    posterior's median (LocationPosterior.point_growth), the fleet's rate where it has no
    inspection, as the service's forecasts do.

    `conditioned`: each tail is conditioned on its own inspections (data.observations), and
    per tail the crack's p05/p50/p95 (over its growth posterior and the weights' posterior,
    jointly sampled, and its path's drift since its latest measurement,
    model.path_variability) and the factor's are added."""
    law = loaded.law
    extra: dict[str, np.ndarray] = {}
    # a tail without inspections (every tail, without `conditioned`) is the fleet's: its
    # posterior is the fleet prior, at the service's point factor for a never-inspected tail
    posterior = loaded.update(tail_evidence(data))
    loads = replace(data.loads, growth_factor=loaded.point_growth(posterior))
    if conditioned:
        factor_q = posterior.factor_quantiles((0.05, 0.5, 0.95)).numpy()
        cracks = loaded.crack_now(
            data.loads,
            data.loads.initial_or(law.initial_crack_m),
            samples=PREDICT_SAMPLES,
            seed=0,
            log_growth=posterior.sample(PREDICT_SAMPLES, seed=0),
        )
        median = np.quantile(cracks.numpy(), 0.5, axis=0)  # the drift moves no median
        since = loaded.drift_origins(data.loads, data.observations)
        cracks = loaded.wander(cracks, since)
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
    trajectory = loaded.trajectory(loads).numpy()  # (aircraft, flights + 1)
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
            "flights_to_critical": _flights_to_critical(trajectory, lengths, law.critical_crack_m),
            **extra,
        }
    )


def _flights_to_critical(trajectory: np.ndarray, lengths: np.ndarray, critical: float) -> pd.Series:
    """First flight count k (k <= the tail's flights) with crack >= critical; <NA> if none."""
    flown = np.arange(trajectory.shape[1])[None, :] <= lengths[:, None]
    reached = (trajectory >= critical) & flown
    first = np.where(reached.any(axis=1), reached.argmax(axis=1), -1)
    return pd.Series(first, dtype="Int64").mask(first < 0)


@command("predict", "predict crack lengths for a flights file", _predict_arguments)
def run_predict(args: argparse.Namespace) -> int:
    if args.out.suffix.lower() not in (".csv", ".parquet"):
        raise CommandError(
            f"{args.out.name}: unknown file type {args.out.suffix!r}; use .csv or .parquet"
        )
    loaded = load_model(args.model)
    growth_law, constants = loaded.growth_law, loaded.law.constants
    flights, recorded = scaled_loads(
        *load_flight_records(args.flights, growth_law, constants), args.stress_factor
    )

    def with_recorded(data: TrainingData) -> TrainingData:
        if recorded is None:
            return data
        return with_cycles(data, recorded, growth_law, constants)

    if args.inspections is None:
        frame = predict_frame(loaded, with_recorded(assemble(flights)), args.history)
        data_tails = flights["tail"].nunique()
    else:
        inspections = location_inspections(
            args.inspections, flights["tail"].unique(), args.location
        )
        data = with_recorded(assemble(flights, inspections, source=args.inspections.name))
        frame = predict_frame(loaded, data, args.history, conditioned=True)
        data_tails = len(data.tails)
    write_table(frame, args.out)
    print(f"wrote {args.out} ({len(frame)} rows, {data_tails} tails)")
    return 0
