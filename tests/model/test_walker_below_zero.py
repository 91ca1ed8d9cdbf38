"""Walker's law below R = 0 as an explicit option (GrowthConstants.gamma_below_zero): the
torch rate, the compiled reductions, the march and the calibration read it alike, and its
default (None) is the law as before."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from model.artifacts import spec_from_dict, spec_to_dict
from model.growth_laws import GROWTH_LAWS, GrowthConstants, fixed_below_zero
from model.hybrid import CrackGrowthModel, ModelSpec
from model.integrate import LoadHistory
from model.physics import ParisLaw
from tests.model.test_growth_laws import BOX, spectrum

WALKER = GROWTH_LAWS["walker"]
# 2024-T3's Walker fit (model/data/materials.csv)
M, GAMMA = 3.59, 0.68


def test_a_fully_reversed_cycle_weighs_what_the_option_says() -> None:
    dk = torch.tensor([10.0, 10.0, 10.0], dtype=torch.float64)
    ratio = torch.tensor([-1.0, 0.0, 0.5], dtype=torch.float64)
    same = WALKER(dk, {"load_ratio": ratio}, GrowthConstants(1e-11, M, GAMMA))
    ignored = WALKER(dk, {"load_ratio": ratio}, GrowthConstants(1e-11, M, GAMMA, None, 0.0))
    # R = -1 with gamma 0: C K_max**m, K_max = dK / 2; above R = 0 nothing changes
    assert float(ignored[0]) == pytest.approx(1e-11 * 5.0**M, rel=1e-12)
    assert torch.equal(ignored[1:], same[1:])
    # the default weighs the reversed cycle 2**(gamma m) = 5.4x as much (issue 41)
    assert float(same[0] / ignored[0]) == pytest.approx(2 ** (GAMMA * M), rel=1e-12)
    assert 5.3 < 2 ** (GAMMA * M) < 5.5


def test_the_compiled_reductions_and_the_calibrations_cycles_agree() -> None:
    cycles = spectrum(4, 30, 6, seed=2)  # R from -0.3 to 0.7, ground-air-ground at -0.1
    below = GrowthConstants(1e-11, M, GAMMA, None, 0.0)
    eq = WALKER.equivalent_range(cycles, below)
    r, s, n = cycles.load_ratio, cycles.stress_range_mpa, cycles.count
    exponent = torch.where(r < 0, torch.zeros_like(r), torch.full_like(r, GAMMA))
    by_hand = (n * (s * (1 - r) ** (exponent - 1)) ** M).sum(-1)
    assert torch.allclose(eq**M, by_hand, rtol=1e-12)
    # flights stored back to back (a cycle file) reduce to the same ranges
    flat = torch.stack((s, r, n), dim=-1)[0].reshape(-1, 3).numpy()
    starts = np.arange(0, flat.shape[0] + 1, 6)
    back_to_back = WALKER.flights_equivalent_range(flat, starts, below)
    np.testing.assert_allclose(back_to_back, eq[0].numpy(), rtol=1e-14)
    # the calibration's cycles: R < 0 moved to R = 0, so any learned gamma leaves them alone
    fixed = fixed_below_zero(cycles, below)
    for gamma in (0.3, GAMMA, 0.9):
        damage = WALKER.flight_damage(
            fixed, torch.tensor(M, dtype=torch.float64), torch.tensor(gamma, dtype=torch.float64)
        )
        want = (
            n
            * (
                s
                * (1 - r)
                ** (torch.where(r < 0, torch.zeros_like(r), torch.full_like(r, gamma)) - 1)
            )
            ** M
        ).sum(-1)
        assert torch.allclose(damage, want, rtol=1e-12)
    # the default is the law as before: one gamma for every R
    same = GrowthConstants(1e-11, M, GAMMA)
    assert fixed_below_zero(cycles, same) is cycles
    one_gamma = (n * (s * (1 - r) ** (GAMMA - 1)) ** M).sum(-1)
    assert torch.allclose(WALKER.equivalent_range(cycles, same) ** M, one_gamma, rtol=1e-12)


def test_the_march_and_the_model_file_carry_it() -> None:
    cycles = spectrum(3, 200, 5, seed=3)
    # reduced under the default: the march reduces it again under each law's constants
    loads = LoadHistory.from_cycles(
        cycles, torch.full((3,), 200), "walker", GrowthConstants(1e-10, M, GAMMA)
    )
    law = ParisLaw(c=1e-10, m=M, gamma=GAMMA, initial_crack_m=0.005)
    ignored = replace(law, gamma_below_zero=0.0)
    grown = {}
    for name, candidate in (("same", law), ("ignored", ignored)):
        spec = ModelSpec(kernel="physics", law=candidate, box=BOX, growth_law="walker")
        grown[name] = CrackGrowthModel(spec).trajectory(loads)[:, -1]
        assert spec_from_dict(spec_to_dict(spec)).law == candidate
    assert bool((grown["ignored"] < grown["same"]).all())  # less damage from R < 0 cycles
    assert "gamma_below_zero" not in spec_to_dict(ModelSpec(kernel="physics", law=law))["law"]
    with pytest.raises(ValueError, match="gamma_below_zero"):
        ParisLaw(gamma_below_zero=1.5)
