"""A user's own beta(a) table (from a handbook, a finite-element model, a test): read as the
march reads every table, linear between its points and held outside them (model.geometry)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from model.crack_cases.base import UNBOUNDED_M, CrackCase, ValidityLimit
from model.geometry import GeometryTable


@dataclass(frozen=True)
class UserTable(CrackCase):
    """crack_length_m (strictly increasing, m) and beta at each; width_m: the section's width
    for net-section yield (null: not checked)."""

    crack_length_m: tuple[float, ...]
    beta_values: tuple[float, ...]
    width_m: float | None = None

    type_name = "table"

    def __post_init__(self) -> None:
        if self.width_m is not None and not self.width_m > 0:
            raise ValueError(f"width_m must be > 0 m, got {self.width_m!r}")
        try:
            GeometryTable.of(self.crack_length_m, self.beta_values)
        except ValueError as exc:
            raise ValueError(f"crack_length_m, beta_values: {exc}") from exc

    @property
    def table(self) -> GeometryTable:
        return GeometryTable.of(self.crack_length_m, self.beta_values)

    def beta(self, crack_length_m: np.ndarray) -> np.ndarray:
        a, knots = np.asarray(crack_length_m, dtype=np.float64), self.table
        return np.interp(a, knots.crack_length_m, knots.factor)

    def validity(self) -> ValidityLimit:
        return ValidityLimit(self.crack_length_m[-1], "the table's last point (held beyond)")

    def extent_m(self) -> float:
        return self.width_m if self.width_m is not None else UNBOUNDED_M

    def extent_reason(self) -> str:
        if self.width_m is None:
            return f"no width given: a_crit searched to a = {UNBOUNDED_M:g} m"
        return "a = W: the crack crosses the width given"

    def net_section_factor(self, crack_length_m: np.ndarray) -> np.ndarray | None:
        if self.width_m is None:
            return None
        return self.width_m / (self.width_m - np.asarray(crack_length_m, dtype=np.float64))
