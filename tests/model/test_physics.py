import math

import pytest
import torch

from model.cells import DamageCell, PhysicsKernel
from model.integrate import march
from model.physics import ParisLaw, paris_closed_form, paris_law, stress_intensity_range


def test_stress_intensity_range_matches_definition():
    dk = stress_intensity_range(
        torch.tensor(100.0, dtype=torch.float64), torch.tensor(0.01, dtype=torch.float64), 1.2
    )
    assert float(dk) == pytest.approx(1.2 * 100.0 * math.sqrt(math.pi * 0.01), rel=1e-12)


def test_paris_law_grows_nothing_for_negative_range():
    rate = paris_law(torch.tensor([-5.0, 10.0]), c=1.5e-11, m=3.8)
    assert float(rate[0]) == 0.0
    assert float(rate[1]) == pytest.approx(1.5e-11 * 10.0**3.8, rel=1e-12)


@pytest.mark.parametrize("field", ["c", "m", "initial_crack_m"])
def test_paris_law_rejects_non_positive_constants(field):
    with pytest.raises(ValueError, match=field):
        ParisLaw(**{field: 0.0})


def test_paris_law_rejects_critical_below_initial():
    with pytest.raises(ValueError, match="critical_crack_m"):
        ParisLaw(critical_crack_m=0.001)


def _euler_final(stress: float, cycles: int, law: ParisLaw) -> float:
    cell = DamageCell(PhysicsKernel(law.geometry_factor), law)
    loads = torch.full((1, cycles), stress, dtype=torch.float64)
    initial = torch.full((1,), law.initial_crack_m, dtype=torch.float64)
    return float(march(cell, loads, initial)[0, -1])


def test_euler_per_cycle_matches_closed_form_under_constant_stress():
    law = ParisLaw()
    euler = _euler_final(130.0, 7300, law)
    exact = float(paris_closed_form(law.initial_crack_m, 130.0, 7300, law))
    # one cycle is tiny against the crack's growth scale: forward Euler is within 0.1 %
    assert euler == pytest.approx(exact, rel=1e-3)
    assert euler < exact  # explicit Euler lags a convex, growing solution


def test_euler_error_falls_first_order_with_step():
    """Halving the step (two half-cycles of the same damage) halves the Euler error."""
    law = ParisLaw(c=1.5e-10)  # faster growth makes the discretisation error measurable
    exact = float(paris_closed_form(law.initial_crack_m, 100.0, 1500, law))  # a: 5 -> 14 mm
    errors = []
    for substeps in (1, 2, 4):
        sub_law = ParisLaw(c=law.c / substeps, m=law.m)
        errors.append(abs(_euler_final(100.0, 1500 * substeps, sub_law) - exact))
    assert errors[0] / errors[1] == pytest.approx(2.0, rel=0.05)
    assert errors[1] / errors[2] == pytest.approx(2.0, rel=0.05)
