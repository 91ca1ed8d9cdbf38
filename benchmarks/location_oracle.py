"""The oracle of benchmarks/locations.py: what a forecaster that knew each location's true law
(its discrepancy and edge included), the fleet's true growth spread and the inspection method's
sizing error would say of each tail from its own measurements, so that each location's scores
read against what its data allow, not only against the goals.

Each tail's growth factor gets its grid posterior (GRID_POINTS values of ln f over +-4 spreads,
the prior N(0, GROWTH_SCATTER**2), each measured crack's likelihood log-normal with the
method's sizing sd), and the true march at every grid value gives its crack after the last
recorded flight (quantiles) and at the horizon's end (P(critical)), as the service's rows."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from app.config import Settings
from benchmarks.location_fleet import (
    GROWTH_SCATTER,
    Place,
    base_law,
    local_stress,
    march_truth,
)

GRID_POINTS = 81
# tails marched together (each at every grid value): ~120 MB of float64 a batch
BATCH_TAILS = 20


def oracle_rows(
    fleet: Any,
    place: Place,
    settings: Settings,
    truth: np.ndarray,
    measured: pd.DataFrame,
    inspected_after: dict[str, int],
    recorded: int,
    horizon_end: int,
) -> pd.DataFrame:
    """One row per tail whose true crack is below a_crit after `recorded` flights, in the
    columns of benchmarks.locations' service rows.  measured: the location's inspections
    (tail, inspection_id, crack_length_m); inspected_after: flights flown before each
    inspection id."""
    critical = base_law(place, settings).critical_crack_m
    log_factor = np.linspace(-4, 4, GRID_POINTS) * GROWTH_SCATTER
    log_prior = -0.5 * (log_factor / GROWTH_SCATTER) ** 2
    local = local_stress(
        fleet.stress_range_mpa[:, :horizon_end], fleet.mission[:, :horizon_end], place
    )
    by_tail = {tail: rows for tail, rows in measured.groupby("tail")}
    rows = []
    for start in range(0, fleet.size, BATCH_TAILS):
        batch = np.arange(start, min(start + BATCH_TAILS, fleet.size))
        cracks = march_truth(
            np.repeat(local[batch], GRID_POINTS, axis=0),
            place,
            settings,
            np.tile(np.exp(log_factor), len(batch)),
        ).reshape(len(batch), GRID_POINTS, -1)
        for k, i in enumerate(batch):
            now = float(truth[i, recorded])
            if now >= critical:
                continue
            tail = fleet.tails[i]
            log_post = log_prior.copy()
            seen = by_tail.get(tail, measured.iloc[:0])
            for inspection, crack in zip(
                seen["inspection_id"], seen["crack_length_m"], strict=True
            ):
                at = cracks[k, :, inspected_after[inspection]]
                log_post -= 0.5 * (np.log(crack / at) / max(place.sizing_sd, 1e-4)) ** 2
            weight = np.exp(log_post - log_post.max())
            weight /= weight.sum()
            p05, p50, p95 = _weighted_quantiles(cracks[k, :, recorded], weight, (0.05, 0.5, 0.95))
            rows.append(
                {
                    "index": int(i),
                    "tail": tail,
                    "true_m": now,
                    "p05_m": p05,
                    "p50_m": p50,
                    "p95_m": p95,
                    "prob_critical": float(weight[cracks[k, :, horizon_end] >= critical].sum()),
                    "reaches": bool(truth[i, horizon_end] >= critical),
                }
            )
    return pd.DataFrame(rows)


def _weighted_quantiles(
    values: np.ndarray, weight: np.ndarray, levels: tuple[float, ...]
) -> list[float]:
    """The values at which the weights' running sum, in the values' order, first reaches each
    level."""
    order = np.argsort(values)
    running = np.cumsum(weight[order])
    picks = np.searchsorted(running, levels).clip(0, len(values) - 1)
    return [float(values[order][j]) for j in picks]
