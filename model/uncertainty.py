"""Forecast uncertainty: a Laplace posterior over the hybrid model's network weights.

Posterior (generalized Gauss-Newton Laplace approximation at the fitted weights theta*).  With
u_i = ln a_pred_i(theta) at the observations, J = du/dtheta (observations, parameters) and W the
observations' likelihood curvatures (model/uncertainty_fit.py, which builds the posterior),

    H = J^T W J + alpha I,      theta ~ N(theta*, H^-1)

J has rank r <= observations, so H^-1 is stored exactly and compactly as an orthonormal basis V
(parameters, r) of the data-informed directions with their data precisions lambda (r,):

    H^-1 = V diag(1 / (lambda + alpha)) V^T + (I - V V^T) / alpha.

Directions the data do not see keep the prior's spread 1 / alpha, which is what widens the bands
where a forecast extrapolates beyond the inspected crack range: the residual kernel's correction
there is set by weights the inspections do not pin down.  Several fits give an equally weighted
mixture of such Gaussians, q(theta) = (1/K) sum_k N(theta_k*, H_k^-1) (why: uncertainty_fit.py).

Forecasts that sample this posterior: model.prognosis.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import torch
from torch import Tensor

from model.flat import flatten
from model.hybrid import CrackGrowthModel

POSTERIOR_KIND = "laplace"
# least sd of ln crack a posterior claims (relative measurement noise), and the noise taken
# where there is no posterior
DEFAULT_NOISE_FLOOR = 0.01


def flat_parameters(model: CrackGrowthModel) -> Tensor:
    """The model's trainable weights as one float64 vector (parameters,), in
    `network_parameters` order."""
    return flatten(list(model.network_parameters().values()))


@dataclass(frozen=True)
class LaplacePosterior:
    """Gaussian posterior N(mean, H^-1) over the flat network parameters (see module docstring).

    mean: (parameters,); prior_precision: (parameters,) alpha_j, one value per layer tensor;
    in whitened coordinates phi = sqrt(alpha) (theta - mean) the prior is N(0, I) and
    H_phi = V diag(precision) V^T + I, with basis V: (parameters, rank) orthonormal and
    precision: (rank,) the data precision along each column.  noise_sd: sigma of ln crack;
    observations: how many the posterior conditions on.  others: further modes of an equally
    weighted mixture (module docstring), each a single mode over the same parameters; the
    fields above describe the first, at the fitted model's weights.
    """

    mean: Tensor
    prior_precision: Tensor
    basis: Tensor
    precision: Tensor
    noise_sd: float
    observations: int
    others: tuple[LaplacePosterior, ...] = ()

    def __post_init__(self) -> None:
        for other in self.others:
            if other.others or other.parameters != self.mean.shape[0]:
                raise ValueError("others must be single modes over as many parameters")
        p = self.mean.shape[0]
        if self.mean.dim() != 1 or self.prior_precision.shape != self.mean.shape:
            raise ValueError("mean and prior_precision must be (parameters,)")
        if self.basis.dim() != 2 or self.basis.shape[0] != p:
            raise ValueError("basis must be (parameters, rank)")
        if self.precision.shape != self.basis.shape[1:]:
            raise ValueError("precision must have one entry per basis column")
        if not bool((self.prior_precision > 0).all()):
            raise ValueError("prior_precision must be > 0")
        if not self.noise_sd > 0:
            raise ValueError(f"noise_sd must be > 0, got {self.noise_sd}")

    @property
    def parameters(self) -> int:
        return int(self.mean.shape[0])

    @property
    def modes(self) -> tuple[LaplacePosterior, ...]:
        """Every mode of the mixture, this one first, each alone (no `others`)."""
        return (replace(self, others=()), *self.others)

    def covariance(self) -> Tensor:
        """Covariance (parameters, parameters) of the posterior: H^-1 for one mode; for a
        mixture of K equally weighted modes, mean_k (H_k^-1 + m_k m_k^T) - m m^T, m = mean_k m_k."""
        if self.others:
            modes = self.modes
            means = torch.stack([mode.mean for mode in modes])  # (modes, parameters)
            centred = means - means.mean(dim=0)
            within = torch.stack([mode.covariance() for mode in modes]).mean(dim=0)
            return within + centred.T @ centred / len(modes)
        v = self.basis
        whitened = (v / (self.precision + 1.0)) @ v.T + torch.eye(self.parameters) - v @ v.T
        scale = self.prior_precision.rsqrt()
        return scale[:, None] * whitened * scale[None, :]

    def sample(self, count: int, seed: int = 0) -> Tensor:
        """count parameter vectors (count, parameters) drawn from the posterior, deterministic for
        seed.  With several modes, sample k comes from mode k mod modes (every mode is drawn
        equally often, whatever the count).  Raises ValueError for count < 1."""
        if count < 1:
            raise ValueError(f"count must be >= 1, got {count}")
        if self.others:
            modes = self.modes
            out = torch.empty(count, self.parameters, dtype=torch.float64)
            for j, mode in enumerate(modes[:count]):
                mode_seed = seed if j == 0 else _mode_seed(seed, j)
                out[j :: len(modes)] = mode._sample_one(len(range(j, count, len(modes))), mode_seed)
            return out
        return self._sample_one(count, seed)

    def _sample_one(self, count: int, seed: int) -> Tensor:
        """count draws (count, parameters) from this mode's Gaussian alone."""
        gen = torch.Generator().manual_seed(seed)
        v = self.basis
        along = torch.randn(count, v.shape[1], generator=gen, dtype=torch.float64)
        free = torch.randn(count, self.parameters, generator=gen, dtype=torch.float64)
        free = free - (free @ v) @ v.T  # the part the data do not see: prior spread
        whitened = (along / torch.sqrt(self.precision + 1.0)) @ v.T + free
        return self.mean + whitened * self.prior_precision.rsqrt()

    def to_dict(self) -> dict[str, Any]:
        """Tensors and a JSON string only (storable with torch.save / weights_only loading)."""
        meta = {
            "kind": POSTERIOR_KIND,
            "noise_sd": self.noise_sd,
            "observations": self.observations,
            "modes": len(self.others) + 1,
        }
        tensors = {
            _mode_key(name, j): getattr(mode, name).detach().cpu().to(torch.float64)
            for j, mode in enumerate(self.modes)
            for name in _TENSORS
        }
        return {**tensors, "meta": json.dumps(meta)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> LaplacePosterior:
        """Inverse of to_dict; raises ValueError for anything else."""
        try:
            meta = json.loads(data["meta"])
            if meta.get("kind") != POSTERIOR_KIND:
                raise ValueError(
                    f"posterior kind must be {POSTERIOR_KIND!r}, got {meta.get('kind')}"
                )
            modes = [
                cls(
                    **{name: data[_mode_key(name, j)].to(torch.float64) for name in _TENSORS},
                    noise_sd=float(meta["noise_sd"]),
                    observations=int(meta["observations"]),
                )
                for j in range(int(meta.get("modes", 1)))
            ]
            return replace(modes[0], others=tuple(modes[1:]))
        except (KeyError, TypeError, AttributeError, IndexError, json.JSONDecodeError) as exc:
            raise ValueError(f"not a posterior dict: {exc!r}") from exc


def _mode_seed(seed: int, mode: int) -> int:
    """An independent generator seed for mode >= 1 of a mixture sampled with `seed`."""
    state = np.random.SeedSequence([seed % 2**64, mode]).generate_state(1, np.uint64)
    return int(state[0] % 2**63)


_TENSORS = ("mean", "prior_precision", "basis", "precision")


def _mode_key(name: str, mode: int) -> str:
    """to_dict's key of a mode's tensor: the first mode's keep their plain names."""
    return name if mode == 0 else f"{name}_{mode}"
