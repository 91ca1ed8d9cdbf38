"""The crack after a given damage under a geometry factor that varies with the crack.

With separable rates, da/dN = C e**z (F(a) dS sqrt(pi a))**m, the crack after damage
D = sum of dS**m satisfies
    H(a) - H(a0) = C e**z D,    H(a) = integral of da / (F(a) sqrt(pi a))**m,
which for a constant F is the closed form model.paris_calibration.physics_log_crack uses.  For
a table F(a) (model.geometry) H has no closed form in m, which the calibration learns, so it is
integrated on a log-a grid (trapezoid in u = ln a, where the integrand a (F sqrt(pi a))**-m is
smooth) and inverted by linear interpolation in u; both are differentiable in m and in the
rate, which is all L-BFGS needs.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

from model.geometry import GeometryTable

# grid points over [min a0, held crack] in ln a: the trapezoid's error in H falls as the
# square of the step (ln 100 / 4096 ~ 1e-3: ~1e-7 relative for smooth F); a table's kinks sit
# between grid points and cost O(step) of one segment only
GRID_POINTS = 4096


def log_integral_grid(
    table: GeometryTable, m: Tensor, smallest_crack_m: float, held_crack_m: float
) -> tuple[Tensor, Tensor]:
    """(GRID_POINTS,) u = ln a from smallest_crack_m to held_crack_m, and H(a) - H(smallest)
    at each (the module's H, in m**(1 - m/2) MPa**-m), float64, differentiable in m."""
    u = torch.linspace(math.log(smallest_crack_m), math.log(held_crack_m), GRID_POINTS)
    u = u.to(torch.float64)
    a = torch.exp(u)
    log_f = torch.log(table.at(a))
    # a / (F sqrt(pi a))**m, in logs: (1 - m/2) u - m ln F - (m/2) ln pi
    log_integrand = (1.0 - 0.5 * m) * u - m * log_f - 0.5 * m * math.log(math.pi)
    integrand = torch.exp(log_integrand)
    steps = 0.5 * (integrand[1:] + integrand[:-1]) * (u[1:] - u[:-1])
    return u, torch.cat((torch.zeros_like(steps[:1]), steps.cumsum(0)))


def table_log_crack(
    log_a0: Tensor,
    log_rate: Tensor,
    cumulative_load: Tensor,
    grid: tuple[Tensor, Tensor],
) -> Tensor:
    """ln a after damage cumulative_load from ln a0, log_rate = ln(C e**z) (F and pi are in
    H), all broadcast together; held at the grid's end (the held crack) past fracture."""
    u, integral = grid
    start = _interpolate(u, integral, log_a0)
    target = start + torch.exp(log_rate) * cumulative_load
    return _interpolate(integral, u, target.clamp_max(integral[-1]))


def _interpolate(x: Tensor, y: Tensor, at: Tensor) -> Tensor:
    """y at `at` by linear interpolation on increasing x (clamped to x's ends)."""
    at = at.clamp(x[0], x[-1])
    k = torch.searchsorted(x.detach(), at.detach().contiguous()).clamp(1, len(x) - 1)
    x0, x1, y0, y1 = x[k - 1], x[k], y[k - 1], y[k]
    return y0 + (y1 - y0) * (at - x0) / (x1 - x0)
