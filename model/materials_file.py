"""A materials table file (the format of model/data/materials.csv), read and checked in full.

Two tables have this format: the shipped one, and a user's own (FLEETPINN_MATERIALS_FILE,
`fleetpinn fit --materials-file`), which is how an operator brings the NASGRO terms of a
licensed database or a test programme (no public source for them could be cited, so the
shipped rows have none).  A user's file is read once at start-up and a bad value would
otherwise surface as a wrong forecast, so every fault is refused there, in one line naming the
file, the line, the material and the column (MaterialsFileError, a ValueError).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from model.nasgro import NasgroTerms

REQUIRED = ("name", "c_m_per_cycle", "m", "gamma", "k_ic_mpa_sqrt_m", "source")
# The NASGRO terms' columns, in NasgroTerms' order (SI: MPa sqrt(m)); all or none in a row
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
# optional, for the critical crack of a crack case (model.crack_cases.residual_strength): the
# plane-stress toughness of thin sheet and the 0.2 % yield strength (MPa sqrt(m), MPa)
STRENGTH_COLUMNS = ("k_c_mpa_sqrt_m", "yield_strength_mpa")
COLUMNS = (*REQUIRED, "note", *NASGRO_COLUMNS, *STRENGTH_COLUMNS)
MAX_NAME = 128  # what the catalogue's material column holds (app.tables.Location)


def _positive(x: float) -> bool:
    return x > 0.0


def _non_negative(x: float) -> bool:
    return x >= 0.0


def _unit(x: float) -> bool:
    return 0.0 <= x <= 1.0


def _below_one(x: float) -> bool:
    return 0.0 <= x < 1.0


def _any(x: float) -> bool:
    return True


# Each numeric column's rule: the test and what the message says it must be
RULES: dict[str, tuple[Callable[[float], bool], str]] = {
    "c_m_per_cycle": (_positive, "> 0"),
    "m": (_positive, "> 0"),
    "gamma": (_unit, "in [0, 1]"),
    "k_ic_mpa_sqrt_m": (_positive, "> 0"),
    "k_c_mpa_sqrt_m": (_positive, "> 0"),
    "yield_strength_mpa": (_positive, "> 0"),
    "nasgro_dk0_mpa_sqrt_m": (_non_negative, ">= 0"),
    "nasgro_kc_mpa_sqrt_m": (_positive, "> 0"),
    "nasgro_p": (_non_negative, ">= 0"),
    "nasgro_q": (_non_negative, ">= 0"),
    "nasgro_alpha": (_positive, "> 0"),
    "nasgro_smax_on_flow_stress": (_below_one, "in [0, 1)"),
    "nasgro_cth_plus": (_any, "a number"),
    "nasgro_cth_minus": (_any, "a number"),
}


class MaterialsFileError(ValueError):
    """A materials file that cannot be used, with the file, line, material and column."""


@dataclass(frozen=True)
class Material:
    """One alloy's Walker fit: C (m per cycle, dK in MPa sqrt(m)), m, gamma (R >= 0) and its
    plane-strain fracture toughness K_IC (MPa sqrt(m)); optionally the NASGRO terms, whose C
    and n are then this row's C and m, and the plane-stress toughness K_c and yield strength
    (MPa) from which a location with a crack case and a limit stress gets its critical crack
    (model.crack_cases.residual_strength; without them a typed a_crit stays the setting).
    citation: the source in full (the shipped table's reference, or a user file's own source
    text); file: the table it came from."""

    name: str
    c: float
    m: float
    gamma: float
    k_ic_mpa_sqrt_m: float
    source: str
    note: str = ""
    nasgro: NasgroTerms | None = None
    citation: str = ""
    file: str = ""
    k_c_mpa_sqrt_m: float | None = None
    yield_strength_mpa: float | None = None


def read_table(path: Path, sources: Mapping[str, str] | None = None) -> dict[str, Material]:
    """The file's rows by material name.  sources: the source keys a row may cite (the shipped
    table); None: any non-empty source text (a user's file).  Raises MaterialsFileError for an
    unreadable file, a missing, unknown or repeated column, a row of the wrong width, an empty
    or repeated name, a missing, non-numeric or out-of-range value, NASGRO columns filled in
    part, or a file without rows.  '#' lines are comments."""
    where = f"materials file {path}"
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc)
        raise MaterialsFileError(f"{where}: cannot read: {reason}") from exc
    numbered = [
        (number, line)
        for number, line in enumerate(text.splitlines(), 1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not numbered:
        raise MaterialsFileError(f"{where}: no header line; columns: {', '.join(COLUMNS)}")
    reader = csv.reader(line for _, line in numbered)
    header = [column.strip() for column in next(reader)]
    _check_header(where, header)
    table: dict[str, Material] = {}
    for cells in reader:
        line = numbered[reader.line_num - 1][0]
        row = _row(f"{where}: line {line}", header, cells)
        material = _material(f"{where}: line {line}", row, sources, str(path))
        if material.name in table:
            raise MaterialsFileError(
                f"{where}: line {line}, material {material.name!r}: "
                "the name is given twice in this file"
            )
        table[material.name] = material
    if not table:
        raise MaterialsFileError(f"{where}: holds no material row, only its header")
    return table


def _check_header(where: str, header: list[str]) -> None:
    for column in header:
        if column not in COLUMNS:
            raise MaterialsFileError(
                f"{where}: header: unknown column {column!r}; columns: {', '.join(COLUMNS)}"
            )
        if header.count(column) > 1:
            raise MaterialsFileError(f"{where}: header: column {column!r} given twice")
    for column in REQUIRED:
        if column not in header:
            raise MaterialsFileError(f"{where}: header: missing column {column!r}")
    nasgro = [column for column in NASGRO_COLUMNS if column in header]
    if nasgro and len(nasgro) < len(NASGRO_COLUMNS):
        missing = next(column for column in NASGRO_COLUMNS if column not in header)
        raise MaterialsFileError(
            f"{where}: header: missing column {missing!r} (the NASGRO columns come all eight "
            "or none)"
        )


def _row(where: str, header: list[str], cells: list[str]) -> dict[str, str]:
    if len(cells) != len(header):
        raise MaterialsFileError(
            f"{where}: {len(cells)} fields, the header has {len(header)} (a comma in a value "
            "needs quotes)"
        )
    return {column: cell.strip() for column, cell in zip(header, cells, strict=True)}


def _material(
    where: str, row: dict[str, str], sources: Mapping[str, str] | None, file: str
) -> Material:
    name = row["name"]
    if not name:
        raise MaterialsFileError(f"{where}, column 'name': a material needs a name")
    if len(name) > MAX_NAME:
        raise MaterialsFileError(f"{where}, column 'name': at most {MAX_NAME} characters")
    where = f"{where}, material {name!r}"
    source = row["source"]
    if not source:
        raise MaterialsFileError(f"{where}, column 'source': say where the constants come from")
    if sources is not None and source not in sources:
        raise MaterialsFileError(
            f"{where}, column 'source': unknown source {source!r}; known: {', '.join(sources)}"
        )
    c, m, gamma, k_ic = (_number(where, row, column) for column in REQUIRED[1:5])
    given = [column for column in NASGRO_COLUMNS if row.get(column)]
    if given and len(given) < len(NASGRO_COLUMNS):
        missing = next(column for column in NASGRO_COLUMNS if column not in given)
        raise MaterialsFileError(
            f"{where}, column {missing!r}: empty, while other NASGRO columns are given "
            "(all eight or none)"
        )
    terms = _nasgro(where, row) if given else None
    citation = source if sources is None else sources[source]
    k_c, yield_strength = (
        _number(where, row, column) if row.get(column) else None for column in STRENGTH_COLUMNS
    )
    return Material(
        name,
        c,
        m,
        gamma,
        k_ic,
        source,
        row.get("note", ""),
        terms,
        citation,
        file,
        k_c_mpa_sqrt_m=k_c,
        yield_strength_mpa=yield_strength,
    )


def _number(where: str, row: dict[str, str], column: str) -> float:
    cell = row.get(column, "")
    if not cell:
        raise MaterialsFileError(f"{where}, column {column!r}: empty; a number is needed")
    try:
        value = float(cell)
    except ValueError:
        raise MaterialsFileError(f"{where}, column {column!r}: not a number: {cell!r}") from None
    test, rule = RULES[column]
    if not (math.isfinite(value) and test(value)):
        raise MaterialsFileError(f"{where}, column {column!r}: must be {rule}, got {cell}")
    return value


def _nasgro(where: str, row: dict[str, str]) -> NasgroTerms:
    values = [_number(where, row, column) for column in NASGRO_COLUMNS]
    if not values[0] < values[1]:
        raise MaterialsFileError(
            f"{where}, column 'nasgro_dk0_mpa_sqrt_m': the threshold must lie below "
            f"nasgro_kc_mpa_sqrt_m ({values[1]:g}), got {values[0]:g}"
        )
    try:
        return NasgroTerms(*values)
    except ValueError as exc:  # what is left: Newman's A0 outside [0, 1) at this alpha
        raise MaterialsFileError(f"{where}, column 'nasgro_alpha': {exc}") from None
