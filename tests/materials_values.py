"""Materials-file rows for the tests: TEST VALUES, chosen to make cracks grow at about the
thesis's Paris rate at R = 0 (C (1 - A0)**n ~ 1.5e-11); they are not, and are not claimed to be,
the constants of any real alloy."""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path

from model.materials_file import COLUMNS, STRENGTH_COLUMNS, Material

# every column but the optional strength ones (tests/model/test_materials_file.py has its own)
HEADER = ",".join(column for column in COLUMNS if column not in STRENGTH_COLUMNS)
# name, C, m, gamma, K_Ic, source, note, then the eight NASGRO terms (dK_0, K_c, p, q, alpha,
# S_max/sigma_0, C_th+, C_th-)
TEST_A = (
    "TEST-NASGRO-A,6.7e-11,3.8,1.0,60,test values,not a real alloy,3.0,60,0.5,1.0,2.0,0.3,1.5,0.1"
)
TEST_B = (
    "TEST-NASGRO-B,9.0e-11,3.5,1.0,55,test values,not a real alloy,2.5,55,0.5,0.5,2.0,0.3,1.5,0.1"
)
# a row replacing a shipped alloy's by name (still test values)
TEST_2024 = "2024-T3,2.0e-11,3.3,0.7,34,test values,override,2.0,50,0.25,0.75,1.9,0.3,1.0,0.0"


def write_materials(path: Path, *rows: str, comment: str = "# TEST VALUES") -> Path:
    """A materials file of `rows` under the full header."""
    path.write_text("\n".join([comment, HEADER, *rows]) + "\n")
    return path


def nasgro_euler(row: Material, stresses: Iterable[float], crack: float) -> float:
    """The physics kernel's march under the NASGRO law at R = 0: one Euler step a flight of
    C (1 - A0)**n dK**n (1 - dK_0/dK)**p / (1 - dK/K_c)**q, dK = S sqrt(pi a) (F = 1)."""
    terms = row.nasgro
    assert terms is not None
    a0 = terms.closure_coefficients()[0]
    dk0, kc = terms.threshold_mpa_sqrt_m, terms.toughness_mpa_sqrt_m
    for stress in stresses:
        dk = stress * math.sqrt(math.pi * crack)
        if dk > dk0:
            crack += (
                row.c
                * ((1.0 - a0) * dk) ** row.m
                * (1.0 - dk0 / dk) ** terms.p
                / (1.0 - dk / kc) ** terms.q
            )
    return crack
