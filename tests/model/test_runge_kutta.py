"""Runge-Kutta cell: convergence order of each tableau, exactness on linear systems, gradients."""

from __future__ import annotations

import itertools
import math

import pytest
import torch
from torch import Tensor, nn
from torch.func import functional_call

from model.cells import EULER, MIDPOINT, RK4, ButcherTableau, RungeKuttaCell, TwoDofDynamics
from model.integrate import march

torch.set_num_threads(1)

OMEGA, ZETA = 2.0 * math.pi, 0.1  # 1 Hz, 10 % of critical damping


class LinearOscillator(nn.Module):
    """x'' + 2 zeta omega x' + omega**2 x = u as the first-order system of state (x, x')."""

    def forward(self, state: Tensor, inputs: Tensor) -> Tensor:
        x, v = state.unbind(-1)
        acc = inputs[..., 0] - 2.0 * ZETA * OMEGA * v - OMEGA**2 * x
        return torch.stack((v, acc), dim=-1)


def oscillator_closed_form(t: float) -> tuple[float, float]:
    """Free response from x = 1, x' = 0: e^(-zeta w t) (cos wd t + zeta w / wd sin wd t)."""
    wd = OMEGA * math.sqrt(1.0 - ZETA**2)
    decay = math.exp(-ZETA * OMEGA * t)
    x = decay * (math.cos(wd * t) + ZETA * OMEGA / wd * math.sin(wd * t))
    v = -decay * OMEGA**2 / wd * math.sin(wd * t)
    return x, v


def oscillator_error(tableau: ButcherTableau, step_s: float, end_s: float = 1.0) -> float:
    steps = round(end_s / step_s)
    cell = RungeKuttaCell(LinearOscillator(), step_s, tableau)
    initial = torch.tensor([[1.0, 0.0]], dtype=torch.float64)
    final = march(cell, torch.zeros(1, steps, 1, dtype=torch.float64), initial)[0, -1]
    exact = torch.tensor(oscillator_closed_form(end_s), dtype=torch.float64)
    return float((final - exact).abs().max())


@pytest.mark.parametrize(("tableau", "order"), [(EULER, 1), (MIDPOINT, 2), (RK4, 4)])
def test_error_falls_with_the_order_of_the_tableau(tableau: ButcherTableau, order: int) -> None:
    # Steps small enough for the asymptotic regime, large enough to stay above rounding.
    steps_s = (0.01, 0.005, 0.0025) if order < 4 else (0.04, 0.02, 0.01)
    errors = [oscillator_error(tableau, h) for h in steps_s]
    ratios = [coarse / fine for coarse, fine in itertools.pairwise(errors)]
    for ratio in ratios:
        assert 2**order * 0.8 < ratio < 2**order * 1.25, (errors, ratios)
    assert tableau.order == order


def test_rk4_on_the_two_dof_system_converges_at_fourth_order() -> None:
    dynamics = TwoDofDynamics((100.0, 110.0, 120.0))
    end_s = 0.4
    force = torch.tensor([1.0, 0.5], dtype=torch.float64)  # constant: no error from holding it

    def final_state(step_s: float) -> Tensor:
        steps = round(end_s / step_s)
        cell = RungeKuttaCell(dynamics, step_s, RK4)
        with torch.no_grad():
            inputs = force.expand(1, steps, 2)
            return march(cell, inputs, torch.zeros(1, 4, dtype=torch.float64))[0, -1]

    reference = final_state(0.0005 / 8)
    errors = [float((final_state(h) - reference).abs().max()) for h in (0.008, 0.004, 0.002)]
    for coarse, fine in itertools.pairwise(errors):
        assert 16 * 0.8 < coarse / fine < 16 * 1.25, errors


def test_one_rk4_step_of_a_linear_system_is_the_fourth_order_taylor_polynomial() -> None:
    matrix = torch.tensor([[0.0, 1.0], [-(OMEGA**2), -2.0 * ZETA * OMEGA]], dtype=torch.float64)
    h = 0.05
    ha = h * matrix
    taylor = torch.eye(2, dtype=torch.float64)
    term = torch.eye(2, dtype=torch.float64)
    for k in range(1, 5):
        term = term @ ha / k
        taylor = taylor + term
    state = torch.tensor([[0.3, -1.2]], dtype=torch.float64)
    stepped = RungeKuttaCell(LinearOscillator(), h, RK4)(
        state, torch.zeros(1, 1, dtype=torch.float64)
    )
    torch.testing.assert_close(stepped, state @ taylor.T, rtol=1e-14, atol=1e-14)


@pytest.mark.parametrize(
    ("a", "b", "c", "message"),
    [
        (((0.0, 1.0), (0.5, 0.0)), (0.0, 1.0), (0.0, 0.5), "lower triangular"),
        (((0.0, 0.0), (0.5, 0.0)), (0.5, 0.6), (0.0, 0.5), "sum to 1"),
        (((0.0, 0.0), (0.5, 0.0)), (0.0, 1.0), (0.0,), "one entry per stage"),
        (((0.0,), (0.5, 0.0)), (0.0, 1.0), (0.0, 0.5), "square"),
    ],
)
def test_invalid_tableau_is_rejected(
    a: tuple[tuple[float, ...], ...], b: tuple[float, ...], c: tuple[float, ...], message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        ButcherTableau(a=a, b=b, c=c, order=2)


def test_non_positive_step_is_rejected() -> None:
    with pytest.raises(ValueError, match="step_s"):
        RungeKuttaCell(LinearOscillator(), 0.0)


def test_two_dof_dynamics_needs_three_dampers() -> None:
    with pytest.raises(ValueError, match="c1, c2, c3"):
        TwoDofDynamics((1.0, 2.0))


@pytest.mark.parametrize("tableau", [EULER, MIDPOINT, RK4])
def test_gradcheck_runge_kutta_cell_in_damping_and_state(tableau: ButcherTableau) -> None:
    cell = RungeKuttaCell(TwoDofDynamics((10.0, 10.0, 10.0)), 0.002, tableau)
    generator = torch.Generator().manual_seed(0)
    state = torch.randn(3, 4, dtype=torch.float64, generator=generator).requires_grad_()
    force = torch.randn(3, 2, dtype=torch.float64, generator=generator)
    damping = torch.tensor([100.0, 110.0, 120.0], dtype=torch.float64, requires_grad=True)

    def step(state: Tensor, damping: Tensor) -> Tensor:
        return functional_call(cell, {"rhs.damping": damping}, (state, force))

    assert torch.autograd.gradcheck(step, (state, damping), eps=1e-6, atol=1e-8, rtol=1e-6)


def test_gradient_through_the_march_matches_finite_differences() -> None:
    cell = RungeKuttaCell(TwoDofDynamics((10.0, 10.0, 10.0)), 0.002, RK4)
    force = torch.ones(1, 25, 2, dtype=torch.float64)
    initial = torch.zeros(1, 4, dtype=torch.float64)

    def displacement(damping: Tensor) -> Tensor:
        def step(state: Tensor, inputs: Tensor) -> Tensor:
            return functional_call(cell, {"rhs.damping": damping}, (state, inputs))

        return march(step, force, initial)[..., :2].sum() * 1e4

    damping = torch.tensor([100.0, 110.0, 120.0], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(displacement, (damping,), eps=1e-4, atol=1e-9, rtol=1e-5)
