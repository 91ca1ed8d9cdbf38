"""benchmarks/sbc.py's scores of a set of fitted fleets (its module docstring says what each is).

Why a second chi-square.  A fleet's tails share every error of its fit (the fleet's centre and
spread, the shape of its factor, the law), so a fleet that is fitted a little high puts most of
its tails above p50 at once: 3,000 tails of 50 fleets are then far fewer than 3,000
independent draws, and the plain chi-square on tails (pit_p) rejects a model whose fleets are
each a fair draw.  pit_p_fleets is Rao and Scott's first-order correction for clustered samples
(Rao & Scott 1981, JASA 76: 221-230; R's survey::svychisq): the statistic is divided by the
mean design effect of the bins, measured from the spread of the bin shares between fleets.  It
equals pit_p where fleets' tails are independent, and still rejects a bias every fleet shares.
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
from scipy.stats import chi2

# the predictive's bins of a held-out value: below p05, p05-p50, p50-p95, above p95
PIT_SHARES = np.array([0.05, 0.45, 0.45, 0.05])
RANK_EDGES = [0, 0.05, 0.5, 0.95, 1.0 + 1e-9]


def pit_p(bins: np.ndarray) -> float:
    """Chi-square p of bin counts against PIT_SHARES (3 degrees of freedom)."""
    total = bins.sum()
    if total == 0:
        return math.nan
    expected = PIT_SHARES * total
    statistic = float(((bins - expected) ** 2 / expected).sum())
    return float(chi2.sf(statistic, 3))


def design_effect(bins_by_fleet: np.ndarray) -> float:
    """Rao and Scott's mean design effect of the pooled bin shares, (fleets, 4) counts: the
    between-fleet (linearised ratio) variance of each share over its variance were every tail
    independent, averaged over the bins with the null shares' weights, N sum_k V_k / pi_k /
    (K - 1).  1 for independent tails; about a fleet's size when each fleet's tails fall
    together."""
    counts = np.asarray(bins_by_fleet, float)
    fleets, total = len(counts), counts.sum()
    if fleets < 2 or total == 0:
        return math.nan
    shares = counts.sum(axis=0) / total
    residual = counts - counts.sum(axis=1, keepdims=True) * shares[None, :]
    variance = fleets / (fleets - 1) * (residual**2).sum(axis=0) / total**2
    return float(total * (variance / PIT_SHARES).sum() / (len(PIT_SHARES) - 1))


def clustered_pit_p(bins_by_fleet: np.ndarray) -> float:
    """pit_p of the pooled bins, (fleets, 4) counts, with the statistic divided by their
    design effect (module docstring)."""
    counts = np.asarray(bins_by_fleet, float)
    pooled = counts.sum(axis=0)
    effect = design_effect(counts)
    if not effect > 0:  # fewer than two fleets, or shares no fleet departs from: not measured
        return math.nan
    expected = PIT_SHARES * pooled.sum()
    statistic = float(((pooled - expected) ** 2 / expected).sum()) / effect
    return float(chi2.sf(statistic, len(PIT_SHARES) - 1))


def _bins(truth: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Counts of truth below p05, in [p05, p50), in [p50, p95] and above p95 of q (tails, 3)."""
    lo, mid, hi = q[:, 0], q[:, 1], q[:, 2]
    return np.array(
        [
            (truth < lo).sum(),
            ((truth >= lo) & (truth < mid)).sum(),
            ((truth >= mid) & (truth <= hi)).sum(),
            (truth > hi).sum(),
        ]
    )


def scores(results: list[dict[str, Any]]) -> dict[str, Any]:
    """The pooled scores of every fleet's tails (benchmarks/sbc.py's docstring)."""
    truth = np.concatenate([r["truth_m"] for r in results])
    q = np.concatenate([np.asarray(r["q_m"], float) for r in results])  # (tails, 3)
    prob = np.concatenate([r["prob_critical"] for r in results])
    critical = np.concatenate([[r["critical_m"]] * len(r["truth_m"]) for r in results])
    inspected = np.concatenate([r["inspected"] for r in results]).astype(bool)
    beyond = np.concatenate([r["beyond"] for r in results]).astype(bool)
    # files before session 31 chose "beyond" by the outcome alone (benchmarks/sbc.py)
    outcome = np.concatenate([r.get("beyond_truth", r["beyond"]) for r in results]).astype(bool)
    z_rank = np.concatenate([r["z_rank"] for r in results])
    fleet = np.concatenate([[k] * len(r["truth_m"]) for k, r in enumerate(results)])
    below = truth < critical  # a crack past a_crit is held: its value says only "reached"
    groups = {
        "inspected": inspected,
        "uninspected": ~inspected,
        "beyond": beyond,
        "beyond_truth": outcome,
    }
    out: dict[str, Any] = {"fleets": len(results), "tails": len(truth)}
    for name, mask in groups.items():
        m = mask & below & np.isfinite(q).all(axis=1)
        t, lo, mid, hi = truth[m], q[m, 0], q[m, 1], q[m, 2]
        # every fleet counts as a cluster, one with no tail in the group too (a domain's estimate)
        by_fleet = np.array(
            [_bins(t[fleet[m] == k], q[m][fleet[m] == k]) for k in range(len(results))]
        )
        bins = by_fleet.sum(axis=0)
        out[name] = {
            "tails": int(m.sum()),
            "cov90": float(np.mean((lo <= t) & (t <= hi))) if m.any() else math.nan,
            "above95": float(np.mean(t > hi)) if m.any() else math.nan,
            "width90_%": float(100 * np.median((hi - lo) / mid)) if m.any() else math.nan,
            "pit_bins": bins.tolist(),
            "pit_p": pit_p(bins),
            "design_effect": design_effect(by_fleet),
            "pit_p_fleets": clustered_pit_p(by_fleet),
        }
    z_by_fleet = np.array(
        [np.histogram(z_rank[inspected & (fleet == k)], RANK_EDGES)[0] for k in range(len(results))]
    )
    z_bins = z_by_fleet.sum(axis=0)
    out["inspected"]["z_pit_bins"] = z_bins.tolist()
    out["inspected"]["z_pit_p"] = pit_p(z_bins)
    out["inspected"]["z_pit_p_fleets"] = clustered_pit_p(z_by_fleet)
    reached = truth >= critical
    table = []
    edges = np.linspace(0, 1, 11)
    for lo_p, hi_p in itertools.pairwise(edges):
        m = (prob >= lo_p) & ((prob < hi_p) if hi_p < 1 else (prob <= hi_p))
        if m.any():
            table.append(
                {
                    "bin": f"{lo_p:.1f}-{hi_p:.1f}",
                    "tails": int(m.sum()),
                    "mean_p": float(prob[m].mean()),
                    "observed": float(reached[m].mean()),
                }
            )
    out["reliability"] = table
    out["brier"] = float(np.mean((prob - reached) ** 2))
    out["reached"] = int(reached.sum())
    return out


def print_scores(summary: dict[str, Any], results: list[dict[str, Any]]) -> None:
    """The scores as a table, then held-90 % by protocol and by geometry, then fit times."""
    print(
        f"{summary['fleets']} fleets, {summary['tails']} tails, {summary['reached']} reach a_crit"
    )
    print(
        f"{'group':<12} {'tails':>6} {'cov90':>6} {'above95':>8} {'width90%':>9} {'pit_p':>8} "
        f"{'deff':>5} {'p_fleets':>8}"
    )
    for group in ("inspected", "uninspected", "beyond", "beyond_truth"):
        g = summary[group]
        print(
            f"{group:<12} {g['tails']:>6} {g['cov90']:>6.3f} {g['above95']:>8.3f} "
            f"{g['width90_%']:>9.1f} {g['pit_p']:>8.3g} {g['design_effect']:>5.1f} "
            f"{g['pit_p_fleets']:>8.3g}   bins {g['pit_bins']}"
        )
    g = summary["inspected"]
    print(
        f"inspected tails' true ln factor: bins {g['z_pit_bins']}, p {g['z_pit_p']:.3g}, "
        f"by fleets {g['z_pit_p_fleets']:.3g}"
    )
    print("P(critical) reliability (bins of >= 20 tails are judged):")
    for row in summary["reliability"]:
        judged = "" if row["tails"] < 20 else f"  |diff| {abs(row['mean_p'] - row['observed']):.3f}"
        print(
            f"  {row['bin']}  {row['tails']:>5} tails  P {row['mean_p']:.3f}  "
            f"observed {row['observed']:.3f}{judged}"
        )
    print(f"Brier {summary['brier']:.4f}")
    for key in ("protocol", "geometry"):
        print(f"held 90 % by {key} (inspected / never inspected / beyond):")
        for value in sorted({r["draw"][key] for r in results}):
            part = scores([r for r in results if r["draw"][key] == value])
            held = " / ".join(
                f"{part[g]['cov90']:.3f}" for g in ("inspected", "uninspected", "beyond")
            )
            print(f"  {value:<10} {held}")
    fit = np.array([r["fit_s"] for r in results])
    print(f"fit + forecast per fleet: median {np.median(fit):.1f} s, max {fit.max():.1f} s")
