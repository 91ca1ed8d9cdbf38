"""Growth-law constants of airframe alloys, as data (model/data/materials.csv), selectable by
name in the settings and the command line.

Each row is a fit of Walker's law, da/dN = C [dK / (1 - R)**(1 - gamma)]**m, from a cited
public source (SOURCES); `law_for` puts its C, m and gamma into the fleet's physics, keeping
the geometry (F, a0, a_crit), which belongs to the structure, not to the alloy.  A table rather
than constants in code, so that a new alloy is a row with its source.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, replace
from functools import cache
from pathlib import Path

from model.physics import ParisLaw

TABLE = Path(__file__).with_name("data") / "materials.csv"

SOURCES = {
    "dowling-2013": (
        "N. E. Dowling, Mechanical Behavior of Materials, 4th ed., Pearson, 2013, "
        "Table 11.2 (constants for the Walker equation; C0 converted from mm to m per cycle)"
    ),
}


@dataclass(frozen=True)
class Material:
    """One alloy's Walker fit: C (m per cycle, dK in MPa sqrt(m)), m, gamma (R >= 0) and its
    plane-strain fracture toughness (MPa sqrt(m), for reference: the critical crack depends on
    the structure's stress and geometry too, so it stays a setting)."""

    name: str
    c: float
    m: float
    gamma: float
    k_ic_mpa_sqrt_m: float
    source: str
    note: str = ""

    @property
    def citation(self) -> str:
        return SOURCES[self.source]


@cache
def materials() -> dict[str, Material]:
    """The table by alloy name."""
    rows = [line for line in TABLE.read_text().splitlines() if not line.startswith("#")]
    table: dict[str, Material] = {}
    for row in csv.DictReader(rows):
        if row["source"] not in SOURCES:
            raise ValueError(f"{TABLE.name}: {row['name']} cites unknown source {row['source']!r}")
        table[row["name"]] = Material(
            row["name"],
            float(row["c_m_per_cycle"]),
            float(row["m"]),
            float(row["gamma"]),
            float(row["k_ic_mpa_sqrt_m"]),
            row["source"],
            row["note"] or "",
        )
    return table


def material(name: str) -> Material:
    """The row named `name`; ValueError naming the known alloys otherwise."""
    table = materials()
    if name not in table:
        raise ValueError(f"unknown material {name!r}; known: {', '.join(table)}")
    return table[name]


def law_for(name: str, physics: ParisLaw | None = None) -> ParisLaw:
    """`physics` (default: the thesis's) with the alloy's C, m and gamma."""
    row = material(name)
    return replace(physics or ParisLaw(), c=row.c, m=row.m, gamma=row.gamma)
