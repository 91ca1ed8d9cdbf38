"""Growth-law constants of airframe alloys, as data, selectable by name in the settings, the
command line and the per-location catalogue.

The shipped table (model/data/materials.csv) holds Walker fits from a cited public source
(SOURCES) and no NASGRO terms (none could be cited; the NASGRO database is licensed).  A user's
own file of the same format (model.materials_file; FLEETPINN_MATERIALS_FILE, `fleetpinn fit
--materials-file`) adds rows, and a row named as a shipped one replaces that row whole: this is
how an operator brings NASGRO terms.  `law_for` puts a row into the fleet's physics, keeping
the geometry (F, a0, a_crit), which belongs to the structure, not to the alloy.
"""

from __future__ import annotations

from dataclasses import replace
from functools import cache, lru_cache
from pathlib import Path

from model.materials_file import Material, read_table
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


@cache
def _shipped() -> dict[str, Material]:
    return read_table(TABLE, SOURCES)


@lru_cache(maxsize=16)
def _user(path: Path) -> dict[str, Material]:
    return read_table(path, None)


def user_table(path: Path | str) -> dict[str, Material]:
    """A user's materials file by name (any source text), read once per process like any
    setting (an edit takes effect at the next start, where it is checked).  Raises
    MaterialsFileError naming the file, line, material and column of the first fault."""
    return dict(_user(Path(path).resolve()))


def materials(extra: Path | str | None = None) -> dict[str, Material]:
    """The table by alloy name: the shipped rows, then `extra`'s (a user's file), which add to
    them and replace a shipped row of the same name."""
    table = dict(_shipped())
    if extra is not None:
        table.update(user_table(extra))
    return table


def material(name: str, extra: Path | str | None = None) -> Material:
    """The row named `name` (of the shipped table and `extra`); ValueError naming the known
    alloys otherwise."""
    table = materials(extra)
    if name not in table:
        raise ValueError(f"unknown material {name!r}; known: {', '.join(table)}")
    return table[name]


def law_for(
    name: str, physics: ParisLaw | None = None, extra: Path | str | None = None
) -> ParisLaw:
    """`physics` (default: the thesis's) with the alloy's C, m, gamma and NASGRO terms (the
    row of the shipped table or of the user's file `extra`)."""
    row = material(name, extra)
    return replace(physics or ParisLaw(), c=row.c, m=row.m, gamma=row.gamma, nasgro=row.nasgro)
