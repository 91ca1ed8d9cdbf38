"""How a fitted crack model is scored: the holdout split of tails and the |% error| metrics.

One definition for every caller: the offline `fleetpinn fit` and the service's retrain report
the same numbers for the same model and inspections.
"""

from __future__ import annotations

import numpy as np
import torch

from model.hybrid import CrackGrowthModel
from model.integrate import LoadHistory, Observations


def holdout_split(n_tails: int, fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(train, validation) tail indices, each sorted: round(fraction * n_tails) tails validate,
    at least 1 when n_tails >= 3 and fraction > 0, never all (at least one tail trains).

    The split is a permutation drawn from numpy's default_rng(seed).  Raises ValueError for a
    negative n_tails or a fraction outside [0, 1).
    """
    if n_tails < 0:
        raise ValueError(f"n_tails must be >= 0, got {n_tails}")
    if not 0 <= fraction < 1:
        raise ValueError(f"fraction must be in [0, 1), got {fraction}")
    n_val = (
        0 if n_tails < 3 or fraction == 0 else min(max(1, round(fraction * n_tails)), n_tails - 1)
    )
    order = np.random.default_rng(seed).permutation(n_tails)
    return np.sort(order[n_val:]), np.sort(order[:n_val])


def select_rows(
    loads: LoadHistory, observations: Observations, rows: np.ndarray
) -> tuple[LoadHistory, Observations]:
    """The loads of `rows` (indices into loads' aircraft) and their observations, re-indexed
    from 0 in the order of `rows`; observations of other rows are dropped."""
    index = torch.from_numpy(rows.astype(np.int64))
    remap = torch.full((loads.lengths.shape[0],), -1, dtype=torch.long)
    remap[index] = torch.arange(len(index))
    keep = remap[observations.aircraft] >= 0
    return loads.select(index), observations.subset(keep, remap[observations.aircraft[keep]])


def abs_percent_errors(
    model: CrackGrowthModel, loads: LoadHistory, observations: Observations
) -> dict[str, float | int]:
    """|a_pred / a_obs - 1| * 100 at the measured observations: count, mean, median and max.

    Non-detections (observations.detected false) hold no crack to compare with and are left
    out; with no measured observation only {"count": 0} is returned.
    """
    if observations.detected is not None:
        observations = observations.subset(observations.detected)
    if observations.aircraft.numel() == 0:
        return {"count": 0}
    with torch.no_grad():
        predicted = model.at(loads, observations)
    error = ((predicted / observations.crack_length_m - 1.0).abs() * 100.0).numpy()
    return {
        "count": int(error.size),
        "mean_abs_pct_error": float(error.mean()),
        "median_abs_pct_error": float(np.median(error)),
        "max_abs_pct_error": float(error.max()),
    }
