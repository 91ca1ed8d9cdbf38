"""The sizing error where nothing measures it, integrated over its prior, and every inspected
tail's prior the fleet spread's posterior (model.tracking's module docstring)."""

import math

import numpy as np
import pytest
import torch

from model.fleet import FleetConfig, generate_fleet, inspect_at
from model.hybrid import CrackGrowthModel, ModelSpec
from model.tracking import SIZING_NODES, SIZING_PRIOR_SD, SizingError, TailEvidence, TrackingPrior
from model.tracking_fit import fit_tracked
from model.tracking_grid import growth_posterior

CONFIG = FleetConfig(aircraft_per_mix=10, years=4, growth_scatter=0.2, seed=5)


def _tracked(rounds: tuple[int, ...], noise_sd: float):
    fleet = generate_fleet(CONFIG)
    fpy = CONFIG.flights_per_year
    chosen = np.arange(fleet.size)
    sample = inspect_at(fleet, chosen, np.array(rounds) * fpy, noise_sd=noise_sd, seed=2)
    evidence = TailEvidence(sample.loads, torch.arange(fleet.size), sample.observations, fleet.size)
    model = CrackGrowthModel(ModelSpec(kernel="physics"))
    return model, evidence, fit_tracked(model, evidence, SizingError())


def test_inspected_once_the_sizing_error_is_integrated_over_its_prior() -> None:
    """One crack a tail cannot tell the sizing error from the spread: SIZING_NODES relative sds
    about the stated one, weights summing to one, each with the spread's posterior under it;
    a tail never inspected draws from all of them."""
    _, _, tracked = _tracked((4,), 0.05)
    nodes = tracked.prior.sizing_nodes
    assert len(nodes) == SIZING_NODES
    assert sum(node.weight for node in nodes) == pytest.approx(1.0)
    spread = sorted(node.relative_sd for node in nodes)
    assert spread[SIZING_NODES // 2] == pytest.approx(0.05)
    assert math.log(spread[-1] / spread[0]) > 2 * SIZING_PRIOR_SD
    assert sum(w for _, w in tracked.prior.uninspected_spread) == pytest.approx(1.0)


def test_measured_by_repeats_one_sizing_error_stands() -> None:
    """Tails measured twice measure the sizing error: one node, at the estimate."""
    _, _, tracked = _tracked((2, 4), 0.08)
    (node,) = tracked.prior.sizing_nodes
    assert "sizing_relative_sd" in tracked.prior.estimated
    assert node.relative_sd == tracked.prior.sizing.relative_sd
    assert node.relative_sd == pytest.approx(0.08, abs=0.02)


def test_a_tail_s_posterior_is_its_posteriors_under_the_nodes_mixed() -> None:
    """Each node's posterior normalised and weighted by the node: a prior of one node at a
    time gives the parts, and their weighted mixture the whole, at every quantile."""
    model, evidence, tracked = _tracked((4,), 0.05)
    prior = tracked.prior
    whole = growth_posterior(model, evidence, prior)
    grid_z = whole.z[:3]
    cdf = torch.zeros_like(grid_z)
    for node in prior.sizing_nodes:
        alone = TrackingPrior(
            prior.growth_sd,
            SizingError(node.relative_sd, prior.sizing.absolute_sd_m),
            prior.estimated,
            growth_mean=prior.growth_mean,
            uninspected_spread=node.spread,
            sizing_nodes=(type(node)(node.relative_sd, 1.0, node.spread),),
        )
        part = growth_posterior(model, evidence, alone)
        for i in range(3):
            cum = torch.cumsum(part.mass[i], 0) - 0.5 * part.mass[i]
            cdf[i] += node.weight * torch.from_numpy(
                np.interp(grid_z[i].numpy(), part.z[i].numpy(), cum.numpy())
            )
    own = torch.cumsum(whole.mass[:3], 1) - 0.5 * whole.mass[:3]
    assert torch.allclose(own, cdf, atol=0.02)


def test_the_nodes_survive_the_model_file() -> None:
    _, _, tracked = _tracked((4,), 0.05)
    again = TrackingPrior.from_dict(tracked.prior.to_dict())
    assert again == tracked.prior
    assert (
        TrackingPrior.from_dict({**tracked.prior.to_dict(), "sizing_nodes": []}).sizing_nodes == ()
    )
