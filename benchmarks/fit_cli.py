"""End-to-end `fleetpinn fit` against the thesis-style reference, measured in the same run.

    .venv/bin/python -m benchmarks.fit_cli [--json] [--discrepancy 0.06] [--seed 0]

Workload: the synthetic fleet (model.fleet), 15 aircraft inspected once at year 5 (uniform
coverage), their 15 x 7,300 flights written as a long-format CSV.  `fleetpinn fit` runs as a
subprocess: reading and validating the files, fitting, writing the model.  The reference is 100
RMSprop epochs of the thesis's MLP#1 cell through a plain per-flight torch loop (the same loop as
benchmarks.speed), on the same 15 aircraft.  Both are wall-clock seconds on one torch thread.
Accuracy is |% error| of the year-5 crack over all aircraft of the fleet, for both models.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import torch

from benchmarks.speed import eager_trajectory, epoch_loss
from model import artifacts
from model.fleet import FleetConfig, generate_fleet, scheduled_inspection
from model.hybrid import CrackGrowthModel, ModelSpec, default_box
from model.records import write_table
from model.runtime import configure_threads
from model.train import warm_start

REFERENCE_EPOCHS = 100


def year5_errors(predicted: torch.Tensor, truth: torch.Tensor) -> dict[str, float]:
    error = (100.0 * (predicted / truth - 1.0)).abs()
    return {"median": float(error.median()), "max": float(error.max())}


def run(discrepancy: float, seed: int) -> dict[str, object]:
    configure_threads(1)
    fleet = generate_fleet(FleetConfig(discrepancy=discrepancy, seed=seed))
    sample = scheduled_inspection(fleet, 15, "uniform-coverage", seed=seed)
    truth = torch.from_numpy(fleet.final_crack_m)
    inspected_tails = {fleet.tails[int(i)] for i in sample.aircraft}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        flights = fleet.flights_frame()
        write_table(flights[flights["tail"].isin(inspected_tails)], folder / "flights.csv")
        write_table(fleet.inspections_frame(sample), folder / "inspections.csv")
        command = [
            str(Path(sys.executable).parent / "fleetpinn"), "fit",
            "--flights", str(folder / "flights.csv"),
            "--inspections", str(folder / "inspections.csv"),
            "--out", str(folder / "model.pt"),
        ]  # fmt: skip
        started = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True)
        cli_s = time.perf_counter() - started
        fitted, _ = artifacts.load(folder / "model.pt")
    with torch.no_grad():
        cli_errors = year5_errors(fitted.final_crack(fleet.loads), truth)

    law = fitted.spec.law
    box = default_box(sample.loads.stress_range_mpa, law)
    reference = CrackGrowthModel(ModelSpec(kernel="mlp", law=law, box=box), seed)
    warm_start(reference)
    optimizer = torch.optim.RMSprop(reference.parameters(), lr=1e-3)
    started = time.perf_counter()
    for _ in range(REFERENCE_EPOCHS):
        optimizer.zero_grad()
        traj = eager_trajectory(reference.kernel, law, sample.loads)
        epoch_loss(traj, sample.observations).backward()
        optimizer.step()
    reference_s = time.perf_counter() - started
    with torch.no_grad():
        reference_errors = year5_errors(reference.final_crack(fleet.loads), truth)
    return {
        "fit_speedup": reference_s / cli_s,
        "cli_fit_s": cli_s,
        "reference_s": reference_s,
        "cli_year5_abs_pct": cli_errors,
        "reference_year5_abs_pct": reference_errors,
        "discrepancy": discrepancy,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON line")
    parser.add_argument(
        "--discrepancy", type=float, default=0.0, help="truth's geometry-factor beta"
    )
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    result = run(args.discrepancy, args.seed)
    if args.json:
        print(json.dumps(result))
        return
    print(f"fleetpinn fit, end to end: {result['cli_fit_s']:.1f} s")
    print(f"{REFERENCE_EPOCHS} eager RMSprop epochs:  {result['reference_s']:.1f} s")
    print(f"speedup: {result['fit_speedup']:.1f}x (goal >= 10)")
    print(f"year-5 |% error| fleetpinn fit: {result['cli_year5_abs_pct']}")
    print(f"year-5 |% error| reference:     {result['reference_year5_abs_pct']}")


if __name__ == "__main__":
    main()
