"""Damping identification of the thesis's 2-DOF system (thesis ch. 3, Table 3.1).

    .venv/bin/python -m benchmarks.two_dof --train data/two_dof/train.csv --test data/two_dof/test.csv
    .venv/bin/python -m benchmarks.two_dof --train data/two_dof/train.csv --test data/two_dof/test.csv --json
    .venv/bin/python -m benchmarks.two_dof --train data/two_dof/train.csv --monte-carlo 20   # study

The files, the simulation and the fit live in model/two_dof.py (CSV columns are described
there); data/two_dof/ holds the thesis's train and test files.  test_rmse compares the
predicted and true displacements of the test file (both masses, every sample) in m.

The Monte Carlo study refits fresh noise (the training file's level, estimated from yT - y)
on the file's true trajectory, with 0, 1 or 2 bursts of heavy noise at random times, and reports
how often each truth lies inside estimate +- 1.96 sd and within the relative goals.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from model.identify import IdentifyConfig
from model.runtime import configure_threads
from model.two_dof import (
    GOAL_RELATIVE,
    TABLE_3_1_BURSTS,
    TEST_COLUMNS,
    TRAIN_COLUMNS,
    TRUE_DAMPING,
    contaminate,
    fit,
    prediction_rmse,
    random_bursts,
    read_two_dof_csv,
)


def run(
    train_path: str | Path, test_path: str | Path, config: IdentifyConfig | None = None
) -> dict[str, object]:
    """Identify on `train_path`, score on `test_path`.

    Returns {"c": [c1, c2, c3], "c_sd": [...], "test_rmse": m, "seconds": s, "iterations": n,
    "converged": bool}.  Raises ValueError / FileNotFoundError for unusable files.
    """
    train = read_two_dof_csv(train_path, TRAIN_COLUMNS)
    test = read_two_dof_csv(test_path, TEST_COLUMNS)
    start = time.perf_counter()
    fitted = fit(train, config)
    seconds = time.perf_counter() - start
    damping = fitted["c"]
    assert isinstance(damping, list)
    return {
        "c": damping,
        "c_sd": fitted["c_sd"],
        "test_rmse": prediction_rmse(damping, test),
        "seconds": seconds,
        "iterations": fitted["iterations"],
        "converged": fitted["converged"],
    }


def write_contaminated_copies(
    train_path: str | Path, out_dir: str | Path, *, seed: int = 0
) -> dict[str, Path]:
    """Write the Table 3.1 training sets into `out_dir`: gaussian.csv (the file as is),
    single_burst.csv and double_burst.csv (the file's noise with TABLE_3_1_BURSTS redrawn).

    Returns {scenario: path}.
    """
    train = read_two_dof_csv(train_path, (*TRAIN_COLUMNS, "y0", "y1"))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {}
    for offset, (name, bursts) in enumerate(TABLE_3_1_BURSTS.items()):
        frame = contaminate(train, bursts, seed=seed + offset, fresh_noise=False)
        paths[name] = out / f"{name}.csv"
        frame.to_csv(paths[name], index=False)
    return paths


def monte_carlo(
    train_path: str | Path,
    repeats: int,
    seed: int = 0,
    config: IdentifyConfig | None = None,
    noise_sd: float | None = None,
) -> dict[str, dict[str, object]]:
    """Refit fresh noise (sd `noise_sd`, default the file's level) with 0, 1 and 2 random
    bursts, `repeats` times each.

    Per scenario: mean estimate, empirical sd of the estimates, mean reported sd, the share of
    fits whose truth lies inside estimate +- 1.96 sd (per parameter and all three at once) and
    the share within GOAL_RELATIVE of the truth.
    """
    train = read_two_dof_csv(train_path, (*TRAIN_COLUMNS, "y0", "y1"))
    truth = np.array(TRUE_DAMPING)
    summary: dict[str, dict[str, object]] = {}
    for count, name in enumerate(("gaussian", "one_burst", "two_bursts")):
        estimates, sds = [], []
        for repeat in range(repeats):
            rng = np.random.default_rng([seed, count, repeat])
            bursts = random_bursts(rng, count)
            frame = contaminate(train, bursts, seed=int(rng.integers(2**31)), noise_sd=noise_sd)
            fitted = fit(frame, config)
            estimates.append(fitted["c"])
            sds.append(fitted["c_sd"])
        c, sd = np.array(estimates), np.array(sds)
        inside = np.abs(c - truth) <= 1.96 * sd
        within = np.abs(c - truth) <= np.array(GOAL_RELATIVE) * truth
        summary[name] = {
            "repeats": repeats,
            "c_mean": c.mean(0).round(2).tolist(),
            "c_empirical_sd": c.std(0, ddof=1).round(2).tolist() if repeats > 1 else None,
            "c_sd_mean": sd.mean(0).round(2).tolist(),
            "covered": inside.mean(0).round(3).tolist(),
            "covered_all": round(float(inside.all(1).mean()), 3),
            "within_goal": within.mean(0).round(3).tolist(),
            "within_goal_all": round(float(within.all(1).mean()), 3),
        }
    return summary


def _summary(result: dict[str, object]) -> str:
    c, sd = result["c"], result["c_sd"]
    assert isinstance(c, list) and isinstance(sd, list)
    lines = ["2-DOF damping identification (RK4 cell, robust least squares through the march)"]
    for i, (value, err) in enumerate(zip(c, sd, strict=True)):
        lines.append(
            f"  c{i + 1} = {value:8.2f} +- {err:6.2f} N s/m   95% interval "
            f"[{value - 1.96 * err:7.2f}, {value + 1.96 * err:7.2f}]   truth {TRUE_DAMPING[i]:.0f}"
        )
    lines.append(f"  test RMSE = {result['test_rmse']:.3e} m")
    lines.append(f"  {result['iterations']} iterations, {result['seconds']:.1f} s")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="benchmarks.two_dof", description=__doc__.split("\n")[0])
    parser.add_argument("--train", required=True, help="training CSV (t,u0,u1,yT0,yT1)")
    parser.add_argument("--test", help="test CSV (t,u0,u1,y0,y1); required unless --monte-carlo")
    parser.add_argument("--json", action="store_true", help="print one JSON line")
    parser.add_argument("--plain", action="store_true", help="plain least squares (not robust)")
    parser.add_argument("--monte-carlo", type=int, metavar="N", help="study N refits per scenario")
    parser.add_argument("--seed", type=int, default=0, help="seed of the Monte Carlo study")
    parser.add_argument(
        "--noise-sd", type=float, help="Monte Carlo base noise sd in m (default: the file's)"
    )
    args = parser.parse_args(argv)
    configure_threads()
    config = IdentifyConfig(robust=not args.plain)
    try:
        if args.monte_carlo is not None:
            if args.monte_carlo < 1:
                parser.error("--monte-carlo needs N >= 1")
            study = monte_carlo(args.train, args.monte_carlo, args.seed, config, args.noise_sd)
            if args.json:
                print(json.dumps(study))
            else:
                for name, row in study.items():
                    print(name, json.dumps(row))
            return 0
        if args.test is None:
            parser.error("--test is required unless --monte-carlo is given")
        result = run(args.train, args.test, config)
    except (ValueError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        keys = ("c", "c_sd", "test_rmse", "seconds")
        print(json.dumps({k: result[k] for k in keys}))
    else:
        print(_summary(result))
    damping = result["c"]
    assert isinstance(damping, list)
    return 0 if all(math.isfinite(v) for v in damping) else 1


if __name__ == "__main__":
    raise SystemExit(main())
