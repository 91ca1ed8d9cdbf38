"""The service subcommands of `fleetpinn`: serve, migrate, worker, retrain, forecast-batch,
seed-demo.  Each one acts on the database named by FLEETPINN_DATABASE_URL (default: fleetpinn.db
in the working directory) through app.commands, imported when the subcommand runs: the offline
subcommands start without FastAPI and SQLAlchemy.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from app.cli.demo import fleet_arguments
from app.cli.progress import Bar
from app.cli.registry import CommandError, command
from model.posterior import kernel_names


def _serve_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--host", default="127.0.0.1", help="interface (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    parser.add_argument(
        "--processes", type=int, default=1, help="API processes on the port (default 1)"
    )


@command("serve", "apply migrations, then serve the HTTP API (docs at /docs)", _serve_arguments)
def run_serve(args: argparse.Namespace) -> int:
    from app import commands

    if args.processes < 1:
        raise CommandError(f"--processes must be >= 1, got {args.processes}")
    commands.serve(args.host, args.port, processes=args.processes)
    return 0


@command("migrate", "bring the database schema to the newest revision", lambda _: None)
def run_migrate(args: argparse.Namespace) -> int:
    from app import commands

    commands.migrate()
    print("database schema is at the newest revision")
    return 0


def _worker_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--once", action="store_true", help="run the queued jobs, then exit (default: poll forever)"
    )
    parser.add_argument(
        "--metrics-port",
        type=int,
        default=None,
        help="serve this worker's Prometheus metrics on http://HOST:PORT/metrics",
    )
    parser.add_argument(
        "--metrics-host",
        default="127.0.0.1",
        help="interface of the metrics (default 127.0.0.1, as `serve`; 0.0.0.0: all)",
    )


@command("worker", "run queued jobs (retrain, forecast-batch) from the database", _worker_arguments)
def run_worker(args: argparse.Namespace) -> int:
    from app import commands

    ran = commands.worker(
        once=args.once, metrics_port=args.metrics_port, metrics_host=args.metrics_host
    )
    if args.once:
        print(f"ran {ran} job(s)")
    return 0


def _retrain_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--kernel", choices=kernel_names(), default=None)
    parser.add_argument("--lbfgs-iterations", type=int, default=None)
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument(
        "--no-activate", action="store_true", help="store the version as a candidate only"
    )


@command("retrain", "train a new model version on every inspected aircraft", _retrain_arguments)
def run_retrain(args: argparse.Namespace) -> int:
    from app import commands

    params = {
        "kernel": args.kernel,
        "lbfgs_iterations": args.lbfgs_iterations,
        "seed": args.seed,
        "activate": not args.no_activate,
    }
    with Bar("retrain") as bar:
        outcome = commands.retrain(
            {k: v for k, v in params.items() if v is not None}, on_progress=bar.update
        )
    print(commands.dumps(outcome))
    return 0 if outcome["status"] == "succeeded" else 1


def _batch_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--out", type=Path, default=None, help="export to .csv, .parquet or .json (ranked)"
    )
    parser.add_argument(
        "--refresh",
        action="store_true",
        help="recompute every tail, not only those without a current forecast",
    )


@command("forecast-batch", "forecast the whole fleet, store and export it", _batch_arguments)
def run_forecast_batch(args: argparse.Namespace) -> int:
    from app import commands

    if args.out is not None and args.out.suffix.lower() not in (".csv", ".parquet", ".json"):
        raise CommandError(f"--out must end in .csv, .parquet or .json, got {args.out.name!r}")
    with Bar("forecast-batch") as bar:
        outcome = commands.forecast_batch(args.out, on_progress=bar.update, refresh=args.refresh)
    print(commands.dumps(outcome))
    return 0 if outcome["status"] == "succeeded" else 1


def _seed_arguments(parser: argparse.ArgumentParser) -> None:
    fleet_arguments(parser)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--growth-scatter",
        type=float,
        default=0.0,
        help="sd of ln growth rate across tails (0: the thesis's world; replicate tests "
        "show ~0.2-0.3)",
    )
    parser.add_argument(
        "--sizing-error",
        type=float,
        default=0.0,
        help="sd of ln(measured / true) of the inspections (0: exact)",
    )


@command("seed-demo", "store the synthetic thesis fleet and its inspections", _seed_arguments)
def run_seed_demo(args: argparse.Namespace) -> int:
    from app import commands

    try:
        with Bar("seed-demo") as bar:
            summary = commands.seed_demo(
                on_progress=bar.update,
                inspected=args.inspected,
                aircraft_per_mix=args.aircraft_per_mix,
                years=args.years,
                seed=args.seed,
                discrepancy=args.discrepancy,
                growth_scatter=args.growth_scatter,
                sizing_error=args.sizing_error,
            )
    except ValueError as exc:
        raise CommandError(str(exc)) from exc
    print(commands.dumps(summary))
    return 0
