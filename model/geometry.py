"""A geometry factor tabulated over crack length: F(a) of a real part rises towards an edge.

Why a table: a crack growing towards a free edge or a hole sees its stress intensity rise well
above F dS sqrt(pi a) with F held at its a0 value (a finite-width factor sqrt(sec(pi a / 2W))
rises by over a third between a = W/2 and 3W/4), and a forecast that marches with F(a0) runs
short exactly where the tails near a_crit are.  Every march (model.cells' kernels, model.fast_march) reads F at the
crack of each step from the same formula, so the torch and compiled marches agree.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise
from typing import Any

import numpy as np
import torch
from torch import Tensor

# the catalogue's bound on a table's points (app.schemas_locations.GeometryTable)
MAX_POINTS = 64


@dataclass(frozen=True)
class GeometryTable:
    """F over crack length: `crack_length_m` (m, strictly increasing) and `factor` (F > 0) at
    each, linear between the points and held at the first / last value outside them.

    Evaluated as F(a) = F_0 + sum_k s_k (clamp(a, a_k, a_k+1) - a_k), s_k the slope of segment
    k: the same arithmetic in torch and in the compiled march, and a derivative dF/da = s_k
    inside segment k (0 outside the table) that both take alike."""

    crack_length_m: tuple[float, ...]
    factor: tuple[float, ...]

    def __post_init__(self) -> None:
        lengths, factors = self.crack_length_m, self.factor
        if not 2 <= len(lengths) <= MAX_POINTS or len(factors) != len(lengths):
            raise ValueError(
                f"crack_length_m and factor must hold the same 2 to {MAX_POINTS} points, got "
                f"{len(lengths)} and {len(factors)}"
            )
        if not all(a > 0 for a in lengths) or any(b <= a for a, b in pairwise(lengths)):
            raise ValueError("crack_length_m must be > 0 and strictly increasing")
        if not all(f > 0 and np.isfinite(f) for f in factors):
            raise ValueError("factor must be finite and > 0")

    @classmethod
    def of(cls, crack_length_m: Sequence[float], factor: Sequence[float]) -> GeometryTable:
        """A table from any sequences (a stored JSON list, the catalogue's entry)."""
        return cls(tuple(float(a) for a in crack_length_m), tuple(float(f) for f in factor))

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> GeometryTable:
        """Inverse of `to_dict`; raises ValueError for anything else."""
        try:
            return cls.of(data["crack_length_m"], data["factor"])
        except (KeyError, TypeError) as exc:
            raise ValueError(f"not a geometry table: {exc!r}") from exc

    def to_dict(self) -> dict[str, list[float]]:
        return {"crack_length_m": list(self.crack_length_m), "factor": list(self.factor)}

    def slopes(self) -> np.ndarray:
        """(points - 1,) dF/da of each segment, per m."""
        a, f = np.asarray(self.crack_length_m), np.asarray(self.factor)
        return np.diff(f) / np.diff(a)

    def at(self, crack_length_m: Tensor) -> Tensor:
        """F at each crack (any shape, m), in its dtype; differentiable in the crack."""
        a = crack_length_m
        out = torch.full_like(a, self.factor[0])
        knots, slopes = self.crack_length_m, self.slopes().tolist()
        for k, slope in enumerate(slopes):
            out = out + slope * (a.clamp(knots[k], knots[k + 1]) - knots[k])
        return out

    def value_at(self, crack_length_m: float) -> float:
        """F at one crack (m), by the same formula as `at`."""
        return float(self.at(torch.tensor([crack_length_m], dtype=torch.float64))[0])
