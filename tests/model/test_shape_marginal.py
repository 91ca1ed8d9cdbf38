"""The shape's marginal likelihood (model.shape_marginal), its compiled parts against
independent references: log Phi against scipy's, the interpolant against the cubic it must
reproduce, and the tails' quadrature against a direct integral of every tail's factor."""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import quad
from scipy.special import log_ndtr

from model.shape_marginal import TailMarginal, _hermite_at, _log_ndtr


def test_log_phi_matches_scipy_from_far_below_to_the_upper_tail() -> None:
    x = np.concatenate([np.linspace(-80.0, 30.0, 20_001), -np.logspace(-8, 4, 500), [-37.0, -1.0]])
    ours = np.array([_log_ndtr(float(v)) for v in x])
    lower = x <= 8.0  # above, log Phi is -Phi(-x) < 1e-15, as exact as erfc's far tail
    assert np.allclose(ours[lower], log_ndtr(x[lower]), rtol=5e-14, atol=0.0)
    assert np.allclose(ours[~lower], log_ndtr(x[~lower]), rtol=1e-11, atol=0.0)


def test_the_interpolant_reproduces_a_cubic_inside_and_its_end_slopes_outside() -> None:
    x = np.array([0.0, 0.3, 1.1, 2.0])
    cubic = np.polynomial.Polynomial([0.5, -1.0, 0.7, 0.2])
    y, slope = cubic(x), cubic.deriv()(x)
    inside = np.linspace(0.0, 2.0, 41)
    assert np.allclose([_hermite_at(x, y, slope, a) for a in inside], cubic(inside), atol=1e-12)
    assert math.isclose(_hermite_at(x, y, slope, -1.0), y[0] - slope[0], rel_tol=1e-12)
    assert math.isclose(_hermite_at(x, y, slope, 3.0), y[-1] + slope[-1], rel_tol=1e-12)


def _direct(c: float, tau: float, rows: dict[str, np.ndarray]) -> float:
    """-log p(cracks | c, tau) by scipy's quad over each tail's factor, for a straight damage
    integral H = exp(ln a) - 1 (a crack of ln a = ln(1 + H) after damage H from ln a = 0)."""
    total = 0.0
    for tail in np.unique(rows["tail"]):
        own = rows["tail"] == tail

        def joint(f: float, own: np.ndarray = own) -> float:
            reached = np.log1p(np.exp(c + f) * rows["damage"][own])
            z = (reached - rows["value"][own]) / rows["sd"][own]
            sign = rows["sign"][own]
            terms = np.where(sign == 0, -0.5 * z**2, log_ndtr(sign * z))
            return math.exp(terms.sum() - 0.5 * (f / tau) ** 2)

        total += math.log(quad(joint, -12 * tau, 12 * tau, points=[0.0], limit=200)[0])
    return -total + len(np.unique(rows["tail"])) * math.log(tau)


def test_the_quadrature_matches_a_direct_integral_of_each_tails_factor() -> None:
    rng = np.random.default_rng(5)
    tails = 6
    tail = np.repeat(np.arange(tails), 2)
    damage = np.tile([0.5, 1.5], tails)
    truth = rng.normal(0.0, 0.2, tails)[tail]
    sd = np.full(len(tail), 0.08)
    value = np.log1p(np.exp(truth) * damage) + rng.normal(0.0, 0.08, len(tail))
    sign = np.zeros(len(tail))
    sign[1], value[1] = 1.0, math.log(1.9)  # past a "critical" crack
    sign[4], value[4] = -1.0, math.log(1.2)  # a no-find
    rows = {"tail": tail, "damage": damage, "value": value, "sd": sd, "sign": sign}
    ln_a = np.linspace(0.0, math.log(8.0), 2001)
    cumulative, integrand = np.expm1(ln_a), np.exp(ln_a)  # H(ln a) and dH / d ln a
    marginal = TailMarginal(ln_a, np.zeros(len(tail)), damage, tail, value, sd, sign)
    for c, tau in ((0.0, 0.2), (0.3, 0.05), (-0.2, 0.6)):
        assert math.isclose(
            marginal(c, tau, cumulative, integrand), _direct(c, tau, rows), abs_tol=2e-4
        )
