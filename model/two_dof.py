"""The thesis's 2-DOF system (thesis ch. 3, Table 3.1): its CSV files, simulation and damping fit.

CSV columns: t (s, uniform step), u0, u1 (forces on masses 1, 2 in N), y0, y1 (true
displacements in m), yT0, yT1 (observed, noisy).  Training needs t, u0, u1, yT0, yT1; the test
file needs t, u0, u1, y0, y1.  The cell is RK4 at the file's step with the force held over each
step, zero initial state, damping started at c = 10, 10, 10 N s/m and identified by
(robust) least squares through the whole march (model.identify).  The repository's copy of the
thesis files is data/two_dof/{train,test}.csv.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from model.cells import RK4, RungeKuttaCell, TwoDofDynamics
from model.identify import IdentifyConfig, identify
from model.integrate import march
from model.physics import TwoDofSystem

INITIAL_DAMPING = (10.0, 10.0, 10.0)
TRUE_DAMPING = (100.0, 110.0, 120.0)  # thesis Table 3.1
GOAL_RELATIVE = (0.05, 0.10, 0.15)  # |c - truth| / truth goals of c1, c2, c3
TRAIN_COLUMNS = ("t", "u0", "u1", "yT0", "yT1")
TEST_COLUMNS = ("t", "u0", "u1", "y0", "y1")


@dataclass(frozen=True)
class Burst:
    """A window [start_s, end_s) whose observation noise is `factor` times the base level."""

    start_s: float
    end_s: float
    factor: float

    def __post_init__(self) -> None:
        if not self.end_s > self.start_s:
            raise ValueError(f"burst needs end_s > start_s, got {self.start_s}, {self.end_s}")
        if not self.factor > 0:
            raise ValueError(f"burst factor must be > 0, got {self.factor}")


# Thesis Table 3.1 / Fig. 3.4d-e; the burst level is not given there, 20x is our choice.
TABLE_3_1_BURSTS: dict[str, tuple[Burst, ...]] = {
    "gaussian": (),
    "single_burst": (Burst(0.5, 0.75, 20.0),),
    "double_burst": (Burst(0.1, 0.2, 20.0), Burst(0.4, 0.5, 20.0)),
}


def read_two_dof_csv(path: str | Path, columns: Sequence[str]) -> pd.DataFrame:
    """Read a 2-DOF CSV and check that `columns` exist, are numeric and finite, and t is uniform.

    Raises ValueError naming the file and the offending column; FileNotFoundError if absent.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    try:
        frame = pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: not a readable CSV file ({exc})") from None
    for column in columns:
        if column not in frame.columns:
            have = ", ".join(map(str, frame.columns)) or "none"
            raise ValueError(f"{path}: missing column {column!r} (columns present: {have})")
        values = pd.to_numeric(frame[column], errors="coerce")
        bad = ~np.isfinite(values.to_numpy(dtype=float))
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise ValueError(
                f"{path}: column {column!r} must be finite numbers; row {row + 2} holds "
                f"{frame[column].iloc[row]!r}"
            )
        frame[column] = values.astype(float)
    if len(frame) < 3:
        raise ValueError(f"{path}: need at least 3 rows, got {len(frame)}")
    step = np.diff(frame["t"].to_numpy())
    if not (step > 0).all() or np.ptp(step) > 1e-6 * step.mean():
        raise ValueError(f"{path}: column 't' must increase by a constant step")
    return frame


def _step_s(frame: pd.DataFrame) -> float:
    return float(np.diff(frame["t"].to_numpy()).mean())


def _forces(frame: pd.DataFrame) -> torch.Tensor:  # (1, steps, 2): force held over each step
    return torch.tensor(frame[["u0", "u1"]].to_numpy()[:-1], dtype=torch.float64).unsqueeze(0)


def simulate(damping: Sequence[float], frame: pd.DataFrame) -> np.ndarray:
    """Displacements (rows, 2) in m of the RK4 march from rest under the frame's forces."""
    cell = RungeKuttaCell(TwoDofDynamics(damping, TwoDofSystem()), _step_s(frame), RK4)
    with torch.no_grad():
        states = march(cell, _forces(frame), torch.zeros(1, 4, dtype=torch.float64))
    return states[0, :, :2].numpy()


def fit(train: pd.DataFrame, config: IdentifyConfig | None = None) -> dict[str, object]:
    """Identify c1, c2, c3 (N s/m) from a training frame; returns c, c_sd, iterations, converged."""
    cell = RungeKuttaCell(TwoDofDynamics(INITIAL_DAMPING, TwoDofSystem()), _step_s(train), RK4)
    observed = torch.tensor(train[["yT0", "yT1"]].to_numpy(), dtype=torch.float64).unsqueeze(0)
    result = identify(
        cell,
        _forces(train),
        observed,
        torch.zeros(1, 4, dtype=torch.float64),
        observed_states=(0, 1),
        config=config,
    )
    return {
        "c": result.parameters.tolist(),
        "c_sd": result.standard_errors.tolist(),
        "iterations": result.iterations,
        "converged": result.converged,
    }


def prediction_rmse(damping: Sequence[float], test: pd.DataFrame) -> float:
    """Root mean square of predicted minus true displacements (m) over the test file."""
    error = simulate(damping, test) - test[["y0", "y1"]].to_numpy()
    return float(np.sqrt(np.mean(error**2)))


def noise_level(frame: pd.DataFrame) -> float:
    """Observation noise sd (m) of a file with true and observed columns: sd of yT - y."""
    residual = frame[["yT0", "yT1"]].to_numpy() - frame[["y0", "y1"]].to_numpy()
    return float(residual.std())


def contaminate(
    frame: pd.DataFrame,
    bursts: Sequence[Burst],
    *,
    seed: int,
    noise_sd: float | None = None,
    fresh_noise: bool = True,
) -> pd.DataFrame:
    """A copy of `frame` whose observed columns carry Gaussian noise plus bursts.

    fresh_noise: yT = y + N(0, noise_sd) everywhere (noise_sd defaults to the file's level);
    otherwise the file's own yT is kept outside the bursts.  Inside each burst the noise is
    redrawn with sd = factor * noise_sd (both masses).  Needs columns t, y0, y1 (and yT0, yT1
    unless fresh_noise).
    """
    sd = noise_level(frame) if noise_sd is None else noise_sd
    rng = np.random.default_rng(seed)
    out = frame.copy()
    true = frame[["y0", "y1"]].to_numpy()
    observed = true + rng.normal(0.0, sd, true.shape)
    if not fresh_noise:
        observed = frame[["yT0", "yT1"]].to_numpy().copy()
    t = frame["t"].to_numpy()
    for burst in bursts:
        inside = (t >= burst.start_s) & (t < burst.end_s)
        observed[inside] = true[inside] + rng.normal(0.0, burst.factor * sd, (inside.sum(), 2))
    out[["yT0", "yT1"]] = observed
    return out


def random_bursts(
    rng: np.random.Generator,
    count: int,
    duration_s: tuple[float, float] = (0.1, 0.25),
    factor: tuple[float, float] = (10.0, 50.0),
    span_s: tuple[float, float] = (0.0, 2.0),
) -> tuple[Burst, ...]:
    """`count` non-overlapping bursts with uniform random duration, placement and factor."""
    bursts: list[Burst] = []
    while len(bursts) < count:
        length = rng.uniform(*duration_s)
        start = rng.uniform(span_s[0], span_s[1] - length)
        candidate = Burst(start, start + length, rng.uniform(*factor))
        if all(candidate.end_s <= b.start_s or candidate.start_s >= b.end_s for b in bursts):
            bursts.append(candidate)
    return tuple(sorted(bursts, key=lambda b: b.start_s))
