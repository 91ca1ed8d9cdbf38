"""Identify the parameters of a recurrent cell from noisy observed trajectories.

Weighted nonlinear least squares through the whole march, solved by Levenberg-Marquardt:

    theta* = argmin_theta  sum_i w_i (y_i - h_i(theta))**2,

where h(theta) are the observed state components of `march(cell_theta, inputs, initial)`.
The Jacobian dh/dtheta comes from the complex step (Squire & Trapp 1998): for a cell that is
real-analytic in its parameters, h(theta + i*eps*e_j) = h(theta) + i*eps*dh/dtheta_j + O(eps**2),
so Im h / eps is the derivative to machine precision (no subtraction, so eps can be tiny).  All
parameter directions go through one vmapped march, so a Jacobian costs about three plain
marches.  Forward-mode autograd gives the same numbers and works for any differentiable cell,
but torch 2.13 runs forward-mode products with Python scalars through Python decompositions
(~0.3 ms per op), which makes it ~30x slower on this march.
Robustness (`robust=True`): the noise may be heteroscedastic (bursts of heavy noise at unknown
times).  Iteratively reweighted least squares weighs every observation by a noise variance
modelled from the current residuals (difference-based, so it holds from the first iteration)
and, once that variance-weighted fit has converged (before, residuals are misfit as much as
noise), by Huber weights on the standardised residuals; standard errors come from Huber's
M-estimator covariance.  The formulas and why: model/robust_noise.py.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import torch
from torch import Tensor, nn
from torch.func import functional_call, jacfwd, vmap

from model.flat import flatten, unflatten
from model.integrate import march
from model.robust_noise import huber_weights, m_estimator_covariance, noise_variance

JacobianMethod = Literal["complex-step", "forward-mode"]
JACOBIAN_METHODS: tuple[str, ...] = ("complex-step", "forward-mode")


@dataclass(frozen=True)
class IdentifyConfig:
    """Solver and robustness settings of `identify`.

    max_iterations: Levenberg-Marquardt steps over both phases (least squares, then reweighted).
    step_tolerance: converged when every parameter moves less than this many standard errors
        (ten times looser for the plain fit that starts a robust one).
    robust: model heteroscedastic noise and down-weight outliers (IRLS); False = plain least squares.
    scale_window: steps in the rolling window of the local noise variance (odd; ~0.1 s at 2 ms).
    burst_alpha: false-alarm probability per window of the test for raised local noise.
    huber_k: Huber threshold in standardised residuals.  3.0 touches 0.3 % of Gaussian samples,
        so clean data give the least-squares optimum; the variance model carries the bursts and
        Huber only bounds what it misses (isolated outliers, the first samples of a burst).
    jacobian: "complex-step" (fast; cell must be real-analytic in its parameters and accept
        complex tensors) or "forward-mode" (torch.func.jacfwd; any differentiable cell, slow).
    """

    max_iterations: int = 60
    step_tolerance: float = 1e-2
    robust: bool = True
    scale_window: int = 51
    burst_alpha: float = 1e-4
    huber_k: float = 3.0
    jacobian: JacobianMethod = "complex-step"

    def __post_init__(self) -> None:
        if self.max_iterations < 1:
            raise ValueError(f"max_iterations must be >= 1, got {self.max_iterations}")
        if not self.step_tolerance > 0:
            raise ValueError(f"step_tolerance must be > 0, got {self.step_tolerance}")
        if self.scale_window < 3 or self.scale_window % 2 == 0:
            raise ValueError(f"scale_window must be an odd number >= 3, got {self.scale_window}")
        if not 0 < self.burst_alpha < 0.5:
            raise ValueError(f"burst_alpha must lie in (0, 0.5), got {self.burst_alpha}")
        if not self.huber_k > 0:
            raise ValueError(f"huber_k must be > 0, got {self.huber_k}")
        if self.jacobian not in JACOBIAN_METHODS:
            raise ValueError(f"jacobian must be one of {JACOBIAN_METHODS}, got {self.jacobian!r}")


@dataclass(frozen=True)
class Identification:
    """Result of `identify`.  Parameters are the cell's trainable ones, flattened in
    `named_parameters()` order; `names` labels each entry, e.g. "rhs.damping[0]".

    noise_sd: (batch, steps + 1, outputs) modelled noise standard deviation per observation
    (uniform, the residuals' dof-corrected rms, unless robust); weights: the final
    least-squares weights w_i (same shape).
    """

    names: tuple[str, ...]
    parameters: Tensor  # (p,)
    standard_errors: Tensor  # (p,)
    covariance: Tensor  # (p, p)
    prediction: Tensor  # (batch, steps + 1, outputs)
    noise_sd: Tensor  # (batch, steps + 1, outputs)
    weights: Tensor  # (batch, steps + 1, outputs)
    iterations: int
    converged: bool

    def state_dict(self, cell: nn.Module) -> dict[str, Tensor]:
        """The identified values shaped as `cell`'s parameters, for `cell.load_state_dict(...,
        strict=False)`."""
        return _by_name(self.parameters, _trainable(cell))


def _trainable(cell: nn.Module) -> list[tuple[str, nn.Parameter]]:
    return [(name, p) for name, p in cell.named_parameters() if p.requires_grad]


def _by_name(flat: Tensor, named: list[tuple[str, nn.Parameter]]) -> dict[str, Tensor]:
    """flat (p,) cut into the shapes of `named`'s parameters, keyed by their names."""
    values = unflatten(flat, [p for _, p in named])
    return {name: value for (name, _), value in zip(named, values, strict=True)}


class ObservedMarch:
    """theta (p,) -> observed states (batch, steps + 1, outputs) of the march of `cell` with
    its trainable parameters (flattened in `named_parameters()` order) set to theta."""

    def __init__(
        self,
        cell: nn.Module,
        inputs: Tensor,
        initial: Tensor,
        observed_states: Sequence[int],
    ) -> None:
        self.cell = cell
        self.inputs, self.initial = inputs, initial
        self.index = torch.tensor(list(observed_states), dtype=torch.long)
        self.trainable = _trainable(cell)

    def __call__(self, theta: Tensor) -> Tensor:
        params = _by_name(theta, self.trainable)

        def step(state: Tensor, inputs: Tensor) -> Tensor:
            return functional_call(self.cell, params, (state, inputs))

        dtype = theta.dtype
        states = march(step, self.inputs.to(dtype), self.initial.to(dtype))
        return states.index_select(-1, self.index)

    def value_and_jacobian(self, theta: Tensor, method: str) -> tuple[Tensor, Tensor]:
        """h(theta) (batch, steps + 1, outputs) and dh/dtheta (batch, steps + 1, outputs, p).

        method: "complex-step" or "forward-mode" (see IdentifyConfig.jacobian).
        """
        if method not in JACOBIAN_METHODS:
            raise ValueError(f"method must be one of {JACOBIAN_METHODS}, got {method!r}")
        p = theta.numel()
        if method == "complex-step":
            # eps * |theta| stays far above the smallest double, far below rounding of theta.
            eps = 1e-20 * theta.abs().clamp_min(1.0)
            probes = theta.to(torch.complex128).expand(p, p) + 1j * torch.diag(eps)
            with torch.no_grad():
                out = vmap(self)(probes)  # (p, batch, steps + 1, outputs)
            value = out[0].real.clone()
            jac = (out.imag / eps.reshape(p, 1, 1, 1)).movedim(0, -1)
            return value, jac
        with torch.no_grad():
            jac = jacfwd(self)(theta)
            value = self(theta)
        return value, jac


def identify(
    cell: nn.Module,
    inputs: Tensor,
    observed: Tensor,
    initial: Tensor,
    observed_states: Sequence[int],
    config: IdentifyConfig | None = None,
    on_iteration: Callable[[int, Tensor], None] | None = None,
) -> Identification:
    """Fit the trainable parameters of `cell` so that its march reproduces `observed`.

    inputs: (batch, steps, inputs) held over each step (e.g. forces in N); observed:
    (batch, steps + 1, outputs) noisy observations at every state of the march, the initial
    one included; initial: (batch, state) known initial state;
    observed_states: which state components are observed (one per output column).  The
    parameters' current values are the starting point; `cell` is not modified.

    Minimises sum_i w_i (observed_i - h_i(theta))**2 by Levenberg-Marquardt (see the module
    docstring for the weights and the covariance).  Raises ValueError on inconsistent shapes
    or when there are no more observations than parameters.
    """
    config = config or IdentifyConfig()
    named = _trainable(cell)
    if not named:
        raise ValueError("cell has no trainable parameters to identify")
    if inputs.dim() != 3 or observed.dim() != 3 or initial.dim() != 2:
        raise ValueError(
            "inputs must be (batch, steps, inputs), observed (batch, steps + 1, outputs) and "
            "initial (batch, state)"
        )
    batch, steps = inputs.shape[:2]
    if observed.shape[:2] != (batch, steps + 1) or initial.shape[0] != batch:
        raise ValueError(
            f"observed must be (batch, steps + 1, outputs) = ({batch}, {steps + 1}, ...) and "
            f"initial ({batch}, state); got {tuple(observed.shape)} and {tuple(initial.shape)}"
        )
    if len(observed_states) != observed.shape[2]:
        raise ValueError(
            f"observed_states names {len(observed_states)} components for "
            f"{observed.shape[2]} observed columns"
        )
    if any(not 0 <= i < initial.shape[1] for i in observed_states):
        raise ValueError(
            f"observed_states must lie in [0, {initial.shape[1]}), got {observed_states}"
        )

    observed = observed.to(torch.float64)
    if not bool(torch.isfinite(observed).all()):
        raise ValueError("observed must be finite (drop or interpolate missing samples)")
    theta = flatten([p for _, p in named])
    n_obs, n_par = observed.numel(), theta.numel()
    if n_obs <= n_par:
        raise ValueError(f"need more observations ({n_obs}) than parameters ({n_par})")
    names = tuple(
        f"{name}[{i}]" if p.numel() > 1 else name for name, p in named for i in range(p.numel())
    )
    model = ObservedMarch(cell, inputs, initial, observed_states)

    def evaluate(th: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        value, jac = model.value_and_jacobian(th, config.jacobian)
        return value, jac, observed - value

    def weigh(residual: Tensor, phase: str) -> tuple[Tensor, Tensor]:
        """(noise sd, least-squares weight) of every observation."""
        if phase == "plain":
            ones = torch.ones_like(residual)
            return ones, ones
        # The floor only keeps noise-free data (zero variance) from dividing by zero.
        variance = noise_variance(residual, config.scale_window, config.burst_alpha)
        variance = variance.clamp_min(1e-300)
        if phase == "variance":
            return variance.sqrt(), 1.0 / variance
        weights = huber_weights(residual / variance.sqrt(), config.huber_k) / variance
        return variance.sqrt(), weights

    value, jac, residual = evaluate(theta)
    noise_sd, weights = weigh(residual, "plain")
    iterations, converged = 0, False
    # Robust: the variance model holds from the start (it ignores smooth misfit); Huber weights
    # join once the residuals are noise rather than misfit.
    phases = ("variance", "huber") if config.robust else ("plain",)
    for phase in phases:
        # A fit that only starts the next phase need not be tight.
        tolerance = config.step_tolerance * (10.0 if phase != phases[-1] else 1.0)
        damping, converged = 1e-3, False
        while iterations < config.max_iterations and not converged:
            iterations += 1
            noise_sd, weights = weigh(residual, phase)
            normal, gradient = _normal_equations(jac, weights, residual)
            cost = float((weights * residual.square()).sum())
            while damping <= 1e12:
                step = torch.linalg.solve(
                    normal + damping * torch.diag(normal.diagonal()), gradient
                )
                t_value, t_jac, t_residual = evaluate(theta + step)
                t_cost = float((weights * t_residual.square()).sum())
                if math.isfinite(t_cost) and t_cost <= cost:
                    damping = max(damping / 10.0, 1e-12)
                    break
                damping *= 10.0
            if damping > 1e12:
                converged = True  # no descent direction left: an optimum at these weights
                break
            theta, value, jac, residual = theta + step, t_value, t_jac, t_residual
            if on_iteration is not None:
                on_iteration(iterations, theta)
            # Converged once the step is small against the current standard errors.
            sd = (cost / (n_obs - n_par) * torch.linalg.inv(normal).diagonal()).sqrt()
            converged = bool((step.abs() <= tolerance * sd).all()) or bool(
                (step.abs() <= 1e-12 * theta.abs().clamp_min(1.0)).all()
            )

    noise_sd, weights = weigh(residual, phases[-1])
    covariance = m_estimator_covariance(
        jac, residual / noise_sd, noise_sd, config.huber_k if config.robust else math.inf
    )
    if not config.robust:
        noise_sd = noise_sd * math.sqrt(float(residual.square().sum()) / (n_obs - n_par))
    return Identification(
        names=names,
        parameters=theta,
        standard_errors=covariance.diagonal().clamp_min(0.0).sqrt(),
        covariance=covariance,
        prediction=value,
        noise_sd=noise_sd,
        weights=weights,
        iterations=iterations,
        converged=converged,
    )


def _normal_equations(jac: Tensor, weights: Tensor, residual: Tensor) -> tuple[Tensor, Tensor]:
    """J^T W J (p, p) and J^T W r (p,) from jac (..., p), weights and residual (...)."""
    p = jac.shape[-1]
    jw = (jac * weights.unsqueeze(-1)).reshape(-1, p)
    return jw.T @ jac.reshape(-1, p), jw.T @ residual.reshape(-1)
