"""The numbers docs/api.md's location section quotes of the crack cases and Walker's law below
R = 0, measured on the service's own code (tests/benchmarks/test_crack_case_claims.py holds
the docs' figures to them):

    PYTHONPATH=. .venv/bin/python -m benchmarks.crack_case_claims

1. The hole fits' long-crack gaps: Bowie's polynomials (model.crack_cases.hole) against the exact
   long-crack limits, two cracks -> sqrt(1 + r/a) (one crack of half-length a + r) and one
   crack -> sqrt((1 + 2r/a)/2) (a crack of length a + 2r), at a/r = 10, 20 and 50.
2. Walker below R = 0: the rate of a fully reversed cycle (R = -1) under 2024-T3's Walker fit
   (model/data/materials.csv) with the default (its gamma below R = 0 too) over the rate with
   gamma_below_zero = 0 (K_max alone): 2**(gamma m).
3. Where the corner crack at a hole ends: its validity limit and the end of its section, in a
   wide plate (a = t, the bore broken through) and a narrow one ((r + c)/b = 0.5 first).
"""

from __future__ import annotations

import numpy as np
import torch

from model.crack_cases.corner import CornerCrackAtHole
from model.crack_cases.hole import CrackAtHole
from model.growth_laws import GROWTH_LAWS, GrowthConstants
from model.materials import material

RATIOS = (10.0, 20.0, 50.0)
# corner cracks at an 8 mm hole: wide (t 5 mm, W 80 mm, a/c 0.8), narrow (t 4 mm, W 40 mm,
# a/c 0.5, where c reaches (r + c)/b = 0.5 at c = 6 mm, a = 3 mm)
CORNERS = {
    "wide": CornerCrackAtHole(0.008, 0.005, 0.08, 0.8),
    "narrow": CornerCrackAtHole(0.008, 0.004, 0.04, 0.5),
}


def hole_gaps(radius_m: float = 0.005) -> dict[int, list[float]]:
    """By number of cracks: 1 - beta / its long-crack limit at each of RATIOS (a/r)."""
    a = np.array(RATIOS) * radius_m
    ratio = np.array(RATIOS)
    limits = {1: np.sqrt((1 + 2 / ratio) / 2), 2: np.sqrt(1 + 1 / ratio)}
    return {
        n: [float(g) for g in 1 - CrackAtHole(2 * radius_m, n).beta(a) / limits[n]] for n in (1, 2)
    }


def reversed_cycle_weight(alloy: str = "2024-T3") -> float:
    """Walker's rate at R = -1 with the alloy's gamma over its rate with gamma_below_zero 0."""
    row = material(alloy)
    walker = GROWTH_LAWS["walker"]
    dk = torch.tensor([10.0], dtype=torch.float64)
    flight = {"load_ratio": torch.tensor([-1.0], dtype=torch.float64)}
    same = walker(dk, flight, GrowthConstants(row.c, row.m, row.gamma))
    ignored = walker(dk, flight, GrowthConstants(row.c, row.m, row.gamma, None, 0.0))
    return float(same[0] / ignored[0])


def corner_ends() -> dict[str, tuple[float, str, float, str]]:
    """By plate: validity limit (m) and why, end of the section (m) and why."""
    return {
        name: (
            case.validity().crack_length_m,
            case.validity().reason,
            case.extent_m(),
            case.extent_reason(),
        )
        for name, case in CORNERS.items()
    }


def main() -> None:
    gaps = hole_gaps()
    for n, label in ((2, "two cracks vs sqrt(1 + r/a)"), (1, "one crack vs sqrt((1 + 2r/a)/2)")):
        said = ", ".join(f"{g:.1%} at a/r = {q:g}" for g, q in zip(gaps[n], RATIOS, strict=True))
        print(f"hole fit below its long-crack limit, {label}: {said}")
    print(f"2024-T3, R = -1: default over gamma_below_zero 0 = {reversed_cycle_weight():.2f}x")
    for name, (valid, why, end, how) in corner_ends().items():
        print(f"corner crack, {name} plate: valid to a = {valid * 1e3:.2f} mm ({why}); "
              f"section ends at a = {end * 1e3:.2f} mm ({how})")  # fmt: skip


if __name__ == "__main__":
    main()
