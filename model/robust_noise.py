"""The noise model of robust identification (model/identify.py): a local noise variance per
observation, Huber weights, and the M-estimator covariance of the result.

The noise may be heteroscedastic (bursts of heavy noise at unknown times).  Iteratively
reweighted least squares models the noise variance of every observation from the current
residuals r (per output channel), difference-based so that smooth model misfit does not count as
noise (it holds from the first iteration):

    e_i      = (r_{i-1} - 2 r_i + r_{i+1}) / sqrt(6)         (E e_i**2 = sigma**2 for white noise)
    v_L, v_R = mean of e**2 over the `scale_window` samples ending at i and starting at i,
    sigma_i**2 = max(v_L, v_R) where a scan test rejects sigma_0**2 in both windows,
                 else sigma_0**2,

with sigma_0 the channel's level outside raised samples (started from the MAD).  The test
compares d v / sigma_0**2 with the chi-square quantile (d = w / 1.94 effective dof, the e_i
being correlated) at false-alarm probability `burst_alpha` per window, so clean data keep
uniform weights (the plain least-squares optimum).  A mean of squares is pushed up by any
heavy-noise sample it holds, so a burst sample fails the test on both sides (each window holds
it); a clean sample beside a burst passes on its clean side and keeps its full weight.  Huber
weights on the standardised residuals z_i = r_i / sigma_i bound the influence of what the
variance model misses (an isolated outlier, the first samples of a burst):
w_i = huber(z_i) / sigma_i**2.

Uncertainty: Huber's M-estimator covariance in whitened coordinates (J~_i = J_i / sigma_i),

    cov = [sum psi(z_i)**2 / (n - p)] / [sum psi'(z_i) / n]**2 * (J~^T J~)^-1,

which, where no residual reaches the Huber threshold and weights are uniform, is the
Gauss-Newton covariance sigma**2 (J^T J)^-1 with sigma**2 = sum r**2 / (n - p).
"""

from __future__ import annotations

import math
from statistics import NormalDist

import torch
from torch import Tensor

# Consistency constant of the MAD for Gaussian noise: sigma = 1.4826 * median |r - median r|.
_MAD_TO_SD = 1.482602218505602


def _window_starts(steps: int, window: int, offset: int) -> Tensor:
    """First index of the length-`window` window of every sample: at i - offset, shifted to stay
    inside [0, steps) so that every window holds `window` samples and contains its sample."""
    return (torch.arange(steps) - offset).clamp(0, steps - window)


def _window_means(x: Tensor, starts: Tensor, window: int) -> Tensor:
    """Means over dim -2 of (..., steps, channels) within [start, start + window) per sample."""
    cum = torch.cat((torch.zeros_like(x[..., :1, :]), x.cumsum(-2)), dim=-2)
    return (cum.index_select(-2, starts + window) - cum.index_select(-2, starts)) / window


def chi2_quantile(probability: float, dof: float) -> float:
    """Wilson-Hilferty approximation of the chi-square quantile (relative error < 1e-3 for
    dof >= 10 in the upper tail)."""
    z = NormalDist().inv_cdf(probability)
    h = 2.0 / (9.0 * dof)
    return dof * (1.0 - h + z * math.sqrt(h)) ** 3


# Pseudo-residuals e_i = (r_{i-1} - 2 r_i + r_{i+1}) / sqrt(6) have E e_i**2 = sigma**2 for white
# noise and are correlated at lags 1 and 2 (rho = -2/3, 1/6), so a mean of w squares carries
# about w / (1 + 2 (4/9 + 1/36)) chi-square degrees of freedom.
_DIFFERENCE_DOF_FACTOR = 1.0 + 2.0 * (4.0 / 9.0 + 1.0 / 36.0)


def noise_variance(residual: Tensor, window: int, alpha: float) -> Tensor:
    """Modelled noise variance of every sample of residuals (batch, steps, channels).

    Difference-based (Gasser, Sroka & Jennen-Steinmetz 1986): second differences of the
    residuals cancel any misfit that is smooth at the sampling step, so the variance model is
    right even far from the optimum.  Each sample lies at the end of one window and at the start
    of another (w samples each); it is "raised" when the scan test rejects the channel's base
    level sigma_0**2 in both windows' mean squared pseudo-residual v.  A raised sample gets the
    larger of its two window variances, any other sigma_0**2.  Requiring both sides marks a
    burst to the sample, while a clean sample beside a burst keeps the base level through its
    clean side.  sigma_0 starts as the MAD scale and is then re-estimated from samples that
    are not raised.
    """
    steps = residual.shape[-2]
    if steps < 3:
        raise ValueError(f"need at least 3 samples for a noise variance, got {steps}")
    window = min(window, steps)
    second = residual[..., :-2, :] - 2.0 * residual[..., 1:-1, :] + residual[..., 2:, :]
    pseudo = torch.cat((second[..., :1, :], second, second[..., -1:, :]), dim=-2) / math.sqrt(6.0)
    square = pseudo.square()
    left = _window_means(square, _window_starts(steps, window, window - 1), window)
    right = _window_means(square, _window_starts(steps, window, 0), window)
    dof = window / _DIFFERENCE_DOF_FACTOR
    limit = chi2_quantile(1.0 - alpha, dof) / dof
    flat = pseudo.transpose(-1, -2)  # (batch, channels, steps)
    base = (_MAD_TO_SD * flat.abs().median(-1, keepdim=True).values).square().transpose(-1, -2)
    for _ in range(3):
        raised = (left > base * limit) & (right > base * limit)
        # A pseudo-residual next to a raised sample holds a burst sample: not base noise either.
        near = raised.clone()
        near[..., 1:, :] |= raised[..., :-1, :]
        near[..., :-1, :] |= raised[..., 1:, :]
        calm = (~near).to(residual.dtype)
        base = (square * calm).sum(-2, keepdim=True) / calm.sum(-2, keepdim=True).clamp_min(1)
    raised = (left > base * limit) & (right > base * limit)
    return torch.where(raised, torch.maximum(torch.maximum(left, right), base), base)


def huber_weights(z: Tensor, k: float) -> Tensor:
    """psi(z)/z of Huber's loss: 1 for |z| <= k, k/|z| beyond."""
    return (k / z.abs().clamp_min(1e-300)).clamp_max(1.0)


def m_estimator_covariance(jac: Tensor, z: Tensor, noise_sd: Tensor, k: float) -> Tensor:
    """Huber's covariance of an M-estimate from the standardised residuals z (see module doc)."""
    n, p = z.numel(), jac.shape[-1]
    whitened = (jac / noise_sd.unsqueeze(-1)).reshape(-1, p)
    psi = z.clamp(-k, k)
    slope = float((z.abs() <= k).to(z.dtype).mean())
    factor = float(psi.square().sum()) / (n - p) / max(slope, 1e-12) ** 2
    return factor * torch.linalg.inv(whitened.T @ whitened)
