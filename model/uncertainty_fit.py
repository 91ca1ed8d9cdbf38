"""Building the Laplace posterior (model/uncertainty.py) of a fitted model's network weights.

With u_i = ln a_pred_i(theta) at the observations and J = du/dtheta, the posterior precision is
H = J^T W J + alpha I, where W = 1 / sigma**2 for a measured crack (ln a_obs ~ N(ln a_pred,
sigma**2)) and, for a non-detection, the curvature of -ln P(not detected | u) (always >= 0, see
`_censored_weight`).

sigma and alpha come from evidence maximisation (MacKay's fixed point): gamma = sum lambda /
(lambda + alpha) well-determined parameters, alpha = gamma / |theta*|**2, sigma**2 =
sum r_i**2 / (measured - gamma), with sigma floored at `noise_floor` (measurement noise: a fit
that interpolates its few inspections must not claim zero noise).

Mixture of modes (multi-start Laplace).  One fit is one mode of a multi-modal posterior, and
it may have stopped short of its mode (TrainConfig's 60 L-BFGS iterations): its correction
then extrapolates beyond the inspected cracks along whatever its hidden features happen to be,
and the Gaussian about it is confidently wrong there.  `laplace_posterior` therefore adds
restarts - 1 further modes, fresh fits of the same spec from other initial weights (run to
convergence, RESTART_CONFIG), each with its own Laplace Gaussian, and the posterior is their
equally weighted mixture: q(theta) = (1/K) sum_k N(theta_k*, H_k^-1).  Inside the data the modes
agree; beyond it their spread adds the disagreement between plausible extrapolations.

Why Laplace rather than a bootstrap ensemble: a few fits plus a Jacobian each (seconds)
instead of 50-100 fits, and any number of samples; point ensembles without the Laplace spread
under-cover.  The measured comparison (single mode, weight decay, multi-start and bootstrap
mixtures, point ensembles) is in benchmarks/CALIBRATION.md.
"""

from __future__ import annotations

import math
from dataclasses import replace

import torch
from torch import Tensor

from model.hybrid import CrackGrowthModel, ModelSpec
from model.integrate import LoadHistory, Observations, detection_scale
from model.train import TrainConfig, fit, warm_start
from model.uncertainty import DEFAULT_NOISE_FLOOR, LaplacePosterior, flat_parameters

DEFAULT_RESTARTS = 9
# restarts fit to convergence: 60 L-BFGS iterations (TrainConfig's default) can stop short
RESTART_CONFIG = TrainConfig(lbfgs_iterations=200)
LAYERS = ("last", "all")


def _observed_subset(
    loads: LoadHistory, observations: Observations
) -> tuple[LoadHistory, Observations]:
    """The observed aircraft's loads (float64) and the observations re-indexed to them."""
    used, local = torch.unique(observations.aircraft, return_inverse=True)
    sub_loads = loads.select(used).to(torch.float64)
    sub_obs = observations.subset(torch.arange(len(local)), local)
    if int((sub_obs.flights > sub_loads.lengths[local]).sum()) > 0:
        raise ValueError("observations: an observation lies after its aircraft's last flight")
    return sub_loads, sub_obs


def log_crack_jacobian(
    model: CrackGrowthModel,
    loads: LoadHistory,
    observations: Observations,
    wanted: Tensor | None = None,
) -> tuple[Tensor, Tensor]:
    """ln a_pred (observations,) and J = d ln a_pred / d theta (observations, parameters).

    Exact adjoint sweeps (one per observation) when there are no more observations than
    parameters; otherwise central differences of the forward march, 2 per parameter (step
    1e-5 (1 + |theta_j|): truncation and rounding ~1e-10 relative), cheaper for long monitoring
    records.  observations index the aircraft of `loads`.  wanted: (parameters,) bool, the
    columns to difference (default all); the others are left 0 (a posterior over the output
    layer alone never reads the hidden layers' columns: 30 of the 43 marches of MLP#1).
    """
    theta = flat_parameters(model)
    loads = model.loads_for(loads)
    stress, lengths = loads.stress_range_mpa.to(torch.float64), loads.lengths
    initial = loads.initial_or(model.spec.law.initial_crack_m)  # (aircraft,) e.g. after repairs
    rows, cols = observations.aircraft, observations.flights

    def log_pred(flat: Tensor) -> Tensor:
        at = (rows, cols)
        return torch.log(
            model.trajectory_with(flat, stress, lengths, initial, loads.growth_factor, at)
        )

    n, p = len(rows), theta.numel()
    if p == 0:
        with torch.no_grad():
            return log_pred(theta), torch.zeros(n, 0, dtype=torch.float64)
    if n <= p:
        leaf = theta.clone().requires_grad_(True)
        values = log_pred(leaf)
        jac = torch.stack(
            [torch.autograd.grad(values[i], leaf, retain_graph=True)[0] for i in range(n)]
        )
        return values.detach(), jac
    with torch.no_grad():
        values = log_pred(theta)
        jac = torch.empty(n, p, dtype=torch.float64)
        for j in range(p):
            if wanted is not None and not bool(wanted[j]):
                jac[:, j] = 0.0
                continue
            step = 1e-5 * (1.0 + abs(float(theta[j])))
            up, down = theta.clone(), theta.clone()
            up[j] += step
            down[j] -= step
            jac[:, j] = (log_pred(up) - log_pred(down)) / (2 * step)
    return values, jac


def _censored_weight(log_pred: Tensor, a50: Tensor, a90: Tensor | None, sd: float) -> Tensor:
    """d^2/du^2 of -ln P(not detected | u = ln a) = m(z) (z + m(z)) / s**2, m = phi/Phi.

    P(not detected) = Phi(z), z = (ln a50 - u) / s, s**2 = s_pod**2 + sd**2 (train.non_detection_nll).
    """
    scale = detection_scale(a50, a90, sd)
    z = (torch.log(a50) - log_pred) / scale
    log_phi = -0.5 * z**2 - 0.5 * math.log(2 * math.pi)
    mills = torch.exp(log_phi - torch.special.log_ndtr(z))
    return mills * (z + mills) / scale**2


def laplace_posterior(
    model: CrackGrowthModel,
    loads: LoadHistory,
    observations: Observations,
    *,
    noise_floor: float = DEFAULT_NOISE_FLOOR,
    prior_precision: float | None = None,
    layers: str = "last",
    iterations: int = 100,
    restarts: int = DEFAULT_RESTARTS,
    restart_config: TrainConfig | None = None,
) -> LaplacePosterior:
    """The Laplace (GGN) posterior of a fitted model's network weights (module docstring).

    loads, observations: what the model was fitted on (observations index aircraft of loads;
    non-detections enter through their likelihood curvature).  noise_floor: least sd of
    ln crack (relative measurement noise).  prior_precision: one alpha for every weight; None =
    evidence maximisation with one alpha per layer tensor (weights, biases of each layer).
    layers: "last" (the output layer's weights and bias are uncertain, the hidden layers stay
    at their fitted values: prior_precision inf there) or "all".  restarts: how many modes the
    posterior mixture has (module docstring; 1 = the single Gaussian at `model`'s weights); the
    first is `model`'s, each further one a fresh fit of the same spec on the observed aircraft
    with `restart_config` (default RESTART_CONFIG; pass the fit's own config to match its loss)
    and seed 1, 2, ...; a restart whose fit or Jacobian is not finite is left out.  The model
    itself is not changed.  Raises ValueError for no observation, noise_floor <= 0,
    prior_precision <= 0, an unknown `layers`, iterations < 1 or restarts < 1.
    """
    if layers not in LAYERS:
        raise ValueError(f"layers must be one of {LAYERS}, got {layers!r}")
    if len(observations.aircraft) == 0:
        raise ValueError("observations: at least one is needed for a posterior")
    if not noise_floor > 0:
        raise ValueError(f"noise_floor must be > 0, got {noise_floor}")
    if prior_precision is not None and not prior_precision > 0:
        raise ValueError(f"prior_precision must be > 0, got {prior_precision}")
    if iterations < 1:
        raise ValueError(f"iterations must be >= 1, got {iterations}")
    if restarts < 1:
        raise ValueError(f"restarts must be >= 1, got {restarts}")
    sub_loads, sub_obs = _observed_subset(loads, observations)
    config = restart_config or RESTART_CONFIG
    modes = []
    for restart in range(restarts if flat_parameters(model).numel() else 1):
        fitted = model if restart == 0 else _refit(model.spec, sub_loads, sub_obs, config, restart)
        mode = None
        if fitted is not None:
            mode = _laplace_mode(
                fitted, sub_loads, sub_obs, noise_floor, prior_precision, layers, iterations
            )
        if mode is None and restart == 0:
            raise ValueError("model: its predicted cracks at the observations are not finite")
        if mode is not None:
            modes.append(mode)
    first, *others = modes
    return replace(first, others=tuple(others))


def _refit(
    spec: ModelSpec, loads: LoadHistory, observations: Observations, config: TrainConfig, seed: int
) -> CrackGrowthModel | None:
    """A fresh model of `spec` fitted from the initial weights of `seed` (the global torch
    generator, which the fit seeds, is left as it was); None when the fit does not end
    finite."""
    with torch.random.fork_rng(devices=[]):
        model = CrackGrowthModel(spec, seed)
        warm_start(model)
        result = fit(model, loads, observations, replace(config, seed=seed))
    finite = math.isfinite(result.final_loss) and bool(flat_parameters(model).isfinite().all())
    return model if finite else None


def _laplace_mode(
    model: CrackGrowthModel,
    sub_loads: LoadHistory,
    sub_obs: Observations,
    noise_floor: float,
    prior_precision: float | None,
    layers: str,
    iterations: int,
) -> LaplacePosterior | None:
    """One Laplace mode at `model`'s weights, observations re-indexed to sub_loads' aircraft;
    None where the predictions or their Jacobian are not finite."""
    theta = flat_parameters(model)
    tensors = list(model.network_parameters().values())
    group = torch.cat(
        [torch.full((t.numel(),), g, dtype=torch.long) for g, t in enumerate(tensors)]
        or [torch.zeros(0, dtype=torch.long)]
    )
    groups = len(tensors)
    # the output layer is the last (weight, bias) pair of the network's tensors
    fixed = torch.tensor(
        [layers == "last" and g < groups - 2 for g in range(groups)], dtype=torch.bool
    )
    # a fixed layer's columns are whitened to 0 (prior precision inf): not differenced
    log_pred, jac = log_crack_jacobian(model, sub_loads, sub_obs, ~fixed[group])
    if not (bool(log_pred.isfinite().all()) and bool(jac.isfinite().all())):
        return None
    group_sq = torch.zeros(groups, dtype=torch.float64).index_add_(0, group, theta**2)
    group_size = torch.bincount(group, minlength=groups).to(torch.float64)
    n = len(log_pred)
    hit = sub_obs.measured
    residual = torch.log(sub_obs.crack_length_m[hit].double()) - log_pred[hit]
    measured = int(hit.sum())
    alpha = torch.full((groups,), prior_precision or 1.0, dtype=torch.float64)
    alpha[fixed] = math.inf
    sigma = max(float(residual.pow(2).mean().sqrt()) if measured else 0.0, noise_floor)
    basis = torch.zeros(theta.numel(), 0, dtype=torch.float64)
    precision = torch.zeros(0, dtype=torch.float64)
    for _ in range(iterations):
        weight = torch.empty(n, dtype=torch.float64)
        weight[hit] = 1.0 / sigma**2
        if not bool(hit.all()):
            assert sub_obs.detection_a50_m is not None
            missed = ~hit
            a90 = None if sub_obs.detection_a90_m is None else sub_obs.detection_a90_m[missed]
            weight[missed] = _censored_weight(
                log_pred[missed], sub_obs.detection_a50_m[missed].double(), a90, sigma
            )
        # whitened Jacobian: the prior is N(0, I) in phi = sqrt(alpha) theta
        whitened = jac * weight.sqrt()[:, None] * alpha[group].rsqrt()[None, :]
        _, singular, vh = torch.linalg.svd(whitened, full_matrices=False)
        keep = singular > singular.max() * 1e-10 if len(singular) else singular > 0
        precision, basis = singular[keep] ** 2, vh[keep].T
        # well-determined parameters per group: 1 - diag(H_phi^-1) summed over the group
        determined = (basis**2 * (precision / (precision + 1.0))).sum(dim=1)
        gamma = torch.zeros(groups, dtype=torch.float64).index_add_(0, group, determined)
        new_sigma = sigma
        if measured:
            dof = max(measured - float(gamma.sum()), 1.0)
            new_sigma = max(math.sqrt(float(residual.pow(2).sum()) / dof), noise_floor)
        new_alpha = alpha
        if prior_precision is None and groups:
            new_alpha = gamma.clamp(1e-3, None).minimum(group_size) / group_sq.clamp_min(1e-12)
            new_alpha[fixed] = math.inf
        free = ~fixed
        change = float((new_alpha[free] / alpha[free] - 1).abs().max()) if free.any() else 0.0
        converged = change < 1e-6 and abs(new_sigma / sigma - 1) < 1e-6
        alpha, sigma = new_alpha, new_sigma
        if converged:
            break
    return LaplacePosterior(theta, alpha[group], basis, precision, float(sigma), n)
