"""Where a location's forecast errs (benchmarks/locations.py --worst N): its worst tails with what
the service saw of them, and the signed p50 error by the tail's true growth draw and by how many
of its inspections were kept, so a miss can be read as scatter, sizing noise or bias."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd


def print_worst(
    name: str,
    scored: pd.DataFrame,
    truth: np.ndarray,
    growth: np.ndarray,
    critical_m: float,
    inspections: pd.DataFrame,
    inspected_at_flights: tuple[int, ...],
    worst: int,
) -> None:
    """Print the `worst` tails by |p50 error| of location `name` (scored: benchmarks.locations'
    per-tail rows), then the signed error's median by growth-draw tercile, by the true crack's
    share of a_crit (critical_m) and by the count of inspections the tail kept.  truth (tails,
    flights + 1) m, growth (tails,) its true growth factor, inspections the location's measurements (tail, inspection_id, crack_length_m)."""
    measured = inspections.pivot_table(
        index="tail", columns="inspection_id", values="crack_length_m", aggfunc="first"
    )
    frame = scored.copy()
    frame["growth"] = growth[frame["index"].to_numpy()]
    frame["kept"] = frame["tail"].map(measured.notna().sum(axis=1)).fillna(0).astype(int)
    order = np.argsort(-np.abs(frame["p50_error"].to_numpy()))[:worst]
    print(f"\n{name}: {worst} largest |p50 error| (crack after the last recorded flight, mm)")
    header = "tail growth " + " ".join(f"true@{f}" for f in inspected_at_flights)
    print(f"{header} measured true p05 p50 p95 error P(crit) reaches")
    for k in order:
        row: Any = frame.iloc[k]
        at = " ".join(f"{1e3 * truth[int(row['index']), f]:.2f}" for f in inspected_at_flights)
        seen = measured.loc[row["tail"]] if row["tail"] in measured.index else pd.Series()
        shown = "/".join(f"{1e3 * v:.2f}" for v in seen.dropna().to_numpy()) or "-"
        print(
            f"{row['tail']} {row['growth']:.2f} {at} {shown} {1e3 * row['true_m']:.2f} "
            f"{1e3 * row['p05_m']:.2f} {1e3 * row['p50_m']:.2f} {1e3 * row['p95_m']:.2f} "
            f"{100 * row['p50_error']:+.1f}% {row['prob_critical']:.2f} {bool(row['reaches'])}"
        )
    terciles = pd.qcut(frame["growth"], 3, labels=["slow", "middle", "fast"])
    by_growth = frame.groupby(terciles, observed=True)["p50_error"]
    print("signed p50 error by growth draw: median (|error| p95, tails)")
    for label, errors in by_growth:
        print(
            f"  {label}: {100 * errors.median():+.2f} % "
            f"({100 * errors.abs().quantile(0.95):.1f} %, {len(errors)})"
        )
    share = pd.cut(frame["true_m"] / critical_m, [0.0, 0.25, 0.5, 0.75, 1.0])
    print("by the true crack's share of a_crit: median (|error| p95, tails)")
    for label, errors in frame.groupby(share, observed=True)["p50_error"]:
        print(
            f"  {label}: {100 * errors.median():+.2f} % "
            f"({100 * errors.abs().quantile(0.95):.1f} %, {len(errors)})"
        )
    for kept, errors in frame.groupby("kept")["p50_error"]:
        print(
            f"  {kept} inspection(s) kept: {100 * errors.median():+.2f} % "
            f"({100 * errors.abs().quantile(0.95):.1f} %, {len(errors)})"
        )
