"""The drift of forecasts beyond their posterior, applied to sampled cracks and whole sampled
paths (model.path_variability estimates its size, path_sd, from held-out later measurements).

A forecast's log growth d = ln(a / a_last) since the tail's latest measurement (where it has
none, since the longest crack the fleet measured: latest_measured) is moved by c = path_sd z,
z ~ N(0, 1) one draw per sample and tail: to d + c d**2 where c >= 0 (model.path_variability's
docstring says why d**2), and where c < 0 to that map's inverse at |c|, 2 d / (1 + sqrt(1 + 4
|c| d)): what the upward drift carries a crack to, the downward drift takes back.  Both agree
with the log error N(0, path_sd**2 d**4) to second order in d, and both keep a path growing
without bound.  Why not d + c d**2 for c < 0 as well: it turns over at d = 1 / (2 |c|) and
never exceeds d = 1 / (4 |c|), so every sample drawn below z = -1 / (4 path_sd ln(a_crit /
a_last)) shrank before a_crit and never reached it, whatever the horizon.  P(critical) was held
under Phi(1 / (4 path_sd ln(a_crit / a_last))): Hudak's alloy-A through the service (path_sd
1.6, ln(a_crit / a_last) 0.35) read 0.59-0.67 for specimens past their lives, at a cap of 0.67
(benchmarks/RESULTS.md, "A drift that never reached a_crit").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
import torch
from torch import Tensor

from model.integrate import LoadHistory, Observations


@numba.njit(cache=True, nogil=True)
def moved_log_growth(d: float, c: float) -> float:
    """The log growth d >= 0 since the latest measurement moved by the drift c = path_sd z
    (module docstring): increasing in d and in c, d itself at c = 0."""
    if c >= 0.0:
        return d + c * d * d
    return 2.0 * d / (1.0 + math.sqrt(1.0 - 4.0 * c * d))


def wander(cracks: Tensor, since_m: Tensor, path_sd: float, seed: int = 0) -> Tensor:
    """cracks (samples, tails) with each sample's log growth since the tail's latest measurement
    (since_m, (tails,)) moved by its own drift (module docstring); unchanged where path_sd is
    0."""
    if path_sd <= 0:
        return cracks
    generator = torch.Generator().manual_seed(seed)
    noise = torch.randn(cracks.shape, generator=generator, dtype=torch.float64)
    drift = PathDrift(path_sd, since_m.to(torch.float64), noise)
    lanes = cracks.reshape(-1, 1)  # sample-major, one point each: PathDrift.moved's lanes
    return drift.moved(lanes, list(range(cracks.shape[0])), math.inf).view_as(cracks)


@dataclass(frozen=True)
class PathDrift:
    """`wander` along whole forecasts: sample k of tail i has its log growth d = ln(a /
    since_m[i]) moved by c = path_sd noise[k, i] (moved_log_growth) at every point of its path
    above since_m, the tail's latest measured crack.  One draw per sample and tail, so a path
    drifts smoothly and its drift grows the farther it extrapolates (a forecast that only moved
    the crack now left bands as narrow as the posterior's once the last flight sat at the last
    inspection: Hudak's alloy-A through the service held 44 % of later measurements where
    `fleetpinn predict` held 90 %, benchmarks/real_data_service.py).

    since_m: (tails,) m; noise: (samples, tails) standard normals (each tail's own seed, so a
    tail's forecast does not depend on the tails sampled with it: PathDrift.drawn)."""

    path_sd: float
    since_m: Tensor
    noise: Tensor

    @classmethod
    def drawn(cls, path_sd: float, since_m: Tensor, samples: int, seeds: list[int]) -> PathDrift:
        """Standard normal noise for each tail from its own seed."""
        columns = [
            torch.randn(samples, generator=torch.Generator().manual_seed(s), dtype=torch.float64)
            for s in seeds
        ]
        noise = torch.stack(columns, dim=1) if columns else torch.zeros(samples, 0)
        return cls(path_sd, since_m.to(torch.float64), noise)

    def select(self, tails: list[int]) -> PathDrift:
        index = torch.tensor(tails, dtype=torch.long)
        return PathDrift(self.path_sd, self.since_m[index], self.noise[:, index])

    def moved(self, trajectory: Tensor, samples: list[int], held_m: float) -> Tensor:
        """trajectory (len(samples) x tails, points), lanes sample-major as
        model.prognosis marches them, each point moved by its sample's and tail's drift; a
        crack held past fracture (held_m) stays held."""
        n, tails = len(samples), self.noise.shape[1]
        coefficient = (self.path_sd * self.noise[samples]).reshape(n * tails)
        since = self.since_m.repeat(n)
        values = trajectory.detach().to(torch.float64).contiguous().numpy()
        out = np.empty_like(values)
        _drift_rows(
            values, coefficient.contiguous().numpy(), since.contiguous().numpy(), held_m, out
        )
        return torch.from_numpy(out).to(trajectory.dtype)


@numba.njit(cache=True, nogil=True)
def _drift_rows(
    cracks: np.ndarray, coefficient: np.ndarray, since: np.ndarray, held: float, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """PathDrift.moved, one element at a time (a scalar loop: each crack moves alike whatever
    else is in the batch)."""
    for row in range(cracks.shape[0]):
        for k in range(cracks.shape[1]):
            a = cracks[row, k]
            if a > since[row] and a < held:
                d = moved_log_growth(math.log(a / since[row]), coefficient[row])
                out[row, k] = since[row] * math.exp(d)
            else:
                out[row, k] = a


def latest_measured(
    loads: LoadHistory, observations: Observations, initial_m: float, fleet_measured_m: float = 0.0
) -> Tensor:
    """(rows,) where `wander`'s drift counts from: each row's latest measured crack; where it
    has none, its initial crack (initial_m where the loads set none) or the longest crack the
    fleet's inspections measured (fleet_measured_m, ModelSpec.measured_up_to_m), the longer.

    Why not from the initial crack: up to the fleet's measured cracks the law was fitted on
    other tails' growth, and the fleet's spread of growth factors carries how far a tail never
    inspected may differ; the drift is what lies beyond.  Counted from a0 it read the log
    growth of a tail's whole life into a drift measured over a fraction of one (the secant
    fleet inspected at years 2 and 4, benchmarks/extrapolation.py: its uninspected tails'
    bands 3x the oracle's width, 11 false alarms against its 10 and 6 without the drift)."""
    since = loads.initial_or(initial_m).double().clamp_min(fleet_measured_m)
    order = torch.argsort(observations.flights, stable=True)
    for k in order[observations.measured[order]].tolist():  # the latest one written last
        since[int(observations.aircraft[k])] = float(observations.crack_length_m[k])
    return since
