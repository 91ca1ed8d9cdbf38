"""Advancing stored crack draws over new flights: the cache's counterpart of
model.fleet_sampling.crack_samples, with the same draws of weights and slopes, so that a row
advanced over its new flights holds what marching its whole history would (the Euler march is
sequential)."""

from __future__ import annotations

import torch
from torch import Tensor

from model.hybrid import CrackGrowthModel
from model.prognosis import LANES_PER_MARCH, sample_groups, weight_draws
from model.uncertainty import LaplacePosterior, flat_parameters


def advance_crack_samples(
    model: CrackGrowthModel,
    weights: LaplacePosterior | None,
    crack_m: Tensor,
    growth_factor: Tensor | None,
    stress_mpa: Tensor,
    lengths: Tensor,
    seed: int,
) -> Tensor:
    """(samples, tails) crack after the flights stress_mpa (tails, flights), sample k from its
    own stored crack crack_m[k] under its own weights (crack_samples' draws for the same seed),
    growth factor growth_factor[k] and shape beyond the measured cracks (the stored cracks are
    under it: marched from where they stand without it, then mapped back)."""
    samples = crack_m.shape[0]
    extrapolation = model.spec.extrapolation
    if extrapolation is None:
        return _march_samples(model, weights, crack_m, growth_factor, stress_mpa, lengths, seed)
    shapes = extrapolation.draws(samples, seed)
    start = extrapolation.within(crack_m, shapes)
    out = _march_samples(model, weights, start, growth_factor, stress_mpa, lengths, seed)
    return extrapolation.beyond(out, shapes)


def _march_samples(
    model: CrackGrowthModel,
    weights: LaplacePosterior | None,
    start: Tensor,
    factor: Tensor | None,
    stress: Tensor,
    lengths: Tensor,
    seed: int,
) -> Tensor:
    """(samples, tails) crack after the flights `stress`, sample k from start[k] under its
    weights and its growth factor factor[k]."""
    samples, tails = start.shape
    out = torch.empty(samples, tails, dtype=torch.float64)
    with torch.no_grad():
        if weights is not None:
            shared = factor is not None  # as crack_samples drew them (weight_draws)
            theta = flat_parameters(model)
            draws = weight_draws(weights, theta, samples, seed, shared)
            for ks in sample_groups(samples, tails, True, shared):
                n, lanes = len(ks), lengths.repeat(len(ks))
                traj = model.trajectory_with(
                    draws[ks[0]],
                    stress.repeat(n, 1),
                    lanes,
                    start[ks].reshape(-1),
                    None if factor is None else factor[ks].reshape(-1),
                )
                out[ks] = traj[torch.arange(n * tails), lanes].view(n, tails)
            return out
        # the fitted weights: every (sample, tail) pair a lane of a few compiled marches
        lane_tail = torch.arange(tails).expand(samples, -1).reshape(-1)
        lane_start = start.reshape(-1)
        lane_factor = None if factor is None else factor.reshape(-1)
        flat = out.view(-1)
        for lo in range(0, len(lane_tail), LANES_PER_MARCH):
            part = lane_tail[lo : lo + LANES_PER_MARCH]
            traj = model(
                stress[part],
                lengths[part],
                lane_start[lo : lo + LANES_PER_MARCH],
                None if lane_factor is None else lane_factor[lo : lo + LANES_PER_MARCH],
            )
            flat[lo : lo + len(part)] = traj[torch.arange(len(part)), lengths[part]]
    return out
