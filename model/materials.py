"""Growth-law constants of airframe alloys, as data (model/data/materials.csv), selectable by
name in the settings and the command line.

Each row is a fit of Walker's law, da/dN = C [dK / (1 - R)**(1 - gamma)]**m, from a cited
public source (SOURCES), and optionally the NASGRO equation's other terms (model.nasgro; the
`nasgro_*` columns, all or none; the row's C and m are then the equation's C and n);
`law_for` puts them into the fleet's physics, keeping the geometry (F, a0, a_crit), which
belongs to the structure, not to the alloy.  A table rather than constants in code, so that a
new alloy is a row with its source.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, replace
from functools import cache
from pathlib import Path

from model.nasgro import NasgroTerms
from model.physics import ParisLaw

TABLE = Path(__file__).with_name("data") / "materials.csv"

SOURCES = {
    "dowling-2013": (
        "N. E. Dowling, Mechanical Behavior of Materials, 4th ed., Pearson, 2013, "
        "Table 11.2 (constants for the Walker equation; C0 converted from mm to m per cycle). "
        "Transcribed by an earlier session; not checked against a readable copy since (none "
        "was found in the public pages, documentation and code searched on 2026-11-27)"
    ),
}

# The NASGRO terms' columns, in NasgroTerms' order (SI: MPa sqrt(m))
NASGRO_COLUMNS = (
    "nasgro_dk0_mpa_sqrt_m",
    "nasgro_kc_mpa_sqrt_m",
    "nasgro_p",
    "nasgro_q",
    "nasgro_alpha",
    "nasgro_smax_on_flow_stress",
    "nasgro_cth_plus",
    "nasgro_cth_minus",
)


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
    nasgro: NasgroTerms | None = None

    @property
    def citation(self) -> str:
        return SOURCES[self.source]


@cache
def materials() -> dict[str, Material]:
    """The table by alloy name."""
    return read_table(TABLE)


def read_table(path: Path) -> dict[str, Material]:
    """A materials table (the format of model/data/materials.csv) by alloy name.  Raises
    ValueError naming the row for an unknown source or NASGRO columns given in part."""
    rows = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    table: dict[str, Material] = {}
    for row in csv.DictReader(rows):
        if row["source"] not in SOURCES:
            raise ValueError(f"{path.name}: {row['name']} cites unknown source {row['source']!r}")
        terms = [row.get(column) or "" for column in NASGRO_COLUMNS]
        if any(terms) and not all(terms):
            raise ValueError(f"{path.name}: {row['name']} gives some NASGRO columns, not all")
        table[row["name"]] = Material(
            row["name"],
            float(row["c_m_per_cycle"]),
            float(row["m"]),
            float(row["gamma"]),
            float(row["k_ic_mpa_sqrt_m"]),
            row["source"],
            row["note"] or "",
            NasgroTerms(*(float(t) for t in terms)) if all(terms) else None,
        )
    return table


def material(name: str) -> Material:
    """The row named `name`; ValueError naming the known alloys otherwise."""
    table = materials()
    if name not in table:
        raise ValueError(f"unknown material {name!r}; known: {', '.join(table)}")
    return table[name]


def law_for(name: str, physics: ParisLaw | None = None) -> ParisLaw:
    """`physics` (default: the thesis's) with the alloy's C, m, gamma and NASGRO terms."""
    row = material(name)
    return replace(physics or ParisLaw(), c=row.c, m=row.m, gamma=row.gamma, nasgro=row.nasgro)
