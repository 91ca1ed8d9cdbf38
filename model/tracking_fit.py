"""Fitting individual aircraft tracking: the fleet prior (its mean and spread by empirical
Bayes, model.fleet_spread), the sizing error from repeated measurements, and the hierarchical
fit of the shared model (model.tracking holds the model, model.tracking_grid the per-tail
posteriors).

Why a joint fit.  A shared model fitted with every tail at the fleet rate reads tail-to-tail
scatter as physics: the tails that grow fastest also hold the longest cracks, so the kernel
learns too much growth at long cracks, or the per-tail factors estimated afterwards absorb the
kernel's missing physics (measured: the largest inspected tails' factors came out twice their
true value and their year-5 cracks 30-60 % short).  `fit_joint` therefore fits the shared
weights and every inspected tail's z together; tau is then re-estimated by empirical Bayes on
the grid, which integrates each z exactly, and the two alternate for a few rounds.

Why the Laplace term.  The joint mode alone, max over theta and z of
sum log p(inspections | theta, z_i) - sum z_i**2 / (2 tau**2), is biased where each tail has few
noisy inspections (the incidental-parameter problem): weights that make a tail's cracks more
sensitive to its z let every z chase its own sizing error, so the kernel learned too steep a
rise with crack length (4 % sizing error, two inspections a tail: +12 to +20 % over the crack
range where the truth's is +6 %, and forecasts near a_crit 30-65 % off at the p95; with exact
inspections it came out right).  The weights are therefore fitted to the Laplace approximation
of the marginal likelihood, which integrates each z out: the joint objective plus
0.5 sum_i log H_i, H_i the curvature of tail i's log posterior in z_i, as nonlinear mixed-effects
software does (Kristensen et al. 2016, TMB).  benchmarks/RESULTS.md has the seeds.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import torch
from torch import Tensor

from model.fleet_spread import estimate_growth_prior, spread_with_evidence
from model.hybrid import CrackGrowthModel
from model.integrate import LoadHistory, Observations
from model.physics import ParisLaw
from model.tracking import (
    SIZING_NODES,
    SIZING_PRIOR_SD,
    TAU_FLOOR,
    GrowthPosterior,
    SizingError,
    SizingNode,
    TailEvidence,
    TrackingPrior,
    surprise_prior,
)
from model.tracking_grid import Grid, build_grid, growth_posterior, observation_log_likelihood
from model.train import FitResult, TrainConfig, fit, minimize_lbfgs

# repeated measurements (beyond each tail's first) needed before the sizing sd is estimated
MIN_SIZING_DOF = 10
# inspected tails needed before the fleet spread is estimated (with one or two, the evidence
# maximum sits at each tail's own deviation); below it the caller's spread stands
MIN_SPREAD_TAILS = 5


# residuals beyond this many sd are read as outliers (a mis-sized or mis-keyed inspection), not
# as sizing error: one such crack among hundreds multiplied the estimate by four
OUTLIER_SD = 4.0


def estimate_relative_sizing_sd(
    grid_ll: Tensor,
    grid: Grid,
    evidence: TailEvidence,
    sizing: SizingError,
    *,
    runaway_crack_m: float,
    shared_parameters: int = 0,
) -> float | None:
    """Relative sizing sd from repeated measurements: the log residuals at each tail's most
    likely z, over (measurements - tails with measurements - shared_parameters) degrees of
    freedom (the shared weights were fitted to the same residuals: without them the sd came
    out 11 % low), less the absolute part; None where fewer than MIN_SIZING_DOF remain.
    Measured cracks that ran away (ParisLaw.runaway_crack_m) and residuals beyond OUTLIER_SD
    are left out."""
    obs = evidence.observations
    hit = obs.measured & (obs.crack_length_m.double() < runaway_crack_m)
    best = grid_ll.argmax(dim=1)  # (tails,)
    predicted = grid.predicted.gather(1, best[evidence.observation_tail][:, None]).squeeze(1)
    residual = torch.log(obs.crack_length_m.double()) - torch.log(predicted)
    variance = None
    for _ in range(2):  # the second pass without the outliers of the first
        tails = evidence.observation_tail[hit]
        counts = torch.bincount(tails, minlength=evidence.tails)
        dof = int((counts - 1).clamp_min(0).sum()) - shared_parameters
        if dof < MIN_SIZING_DOF:
            return None
        repeated = hit & (counts[evidence.observation_tail] > 1)
        total = float(residual[repeated].pow(2).sum())
        absolute = float(((sizing.absolute_sd_m / predicted[repeated]) ** 2).mean())
        variance = max(total / dof - absolute, 1e-6)
        hit = hit & (residual.abs() <= OUTLIER_SD * math.sqrt(variance + absolute))
    assert variance is not None
    return math.sqrt(variance)


def fit_prior(
    model: CrackGrowthModel,
    evidence: TailEvidence,
    sizing: SizingError,
    *,
    estimate_sizing: bool = True,
    growth_sd: float = 0.0,
) -> tuple[TrackingPrior, Grid]:
    """The fleet prior from the inspected tails (module docstring): mu and tau by empirical
    Bayes where at least MIN_SPREAD_TAILS tails are inspected (else mu 0 and tau `growth_sd`:
    one or two tails say too little of a fleet; the shared fit carries what they show), the
    relative sizing sd from repeated measurements where there are enough."""
    grid = build_grid(model, evidence, sizing)
    estimated: list[str] = []
    if estimate_sizing:
        shared = sum(p.numel() for p in model.network_parameters().values())
        relative = estimate_relative_sizing_sd(
            grid.log_likelihood(evidence, sizing),
            grid,
            evidence,
            sizing,
            runaway_crack_m=model.spec.law.runaway_crack_m,
            shared_parameters=shared,
        )
        if relative is not None:
            sizing = replace(sizing, relative_sd=relative)
            estimated.append("sizing_relative_sd")
    informed = evidence.informed
    if int(informed.sum()) < MIN_SPREAD_TAILS:
        return TrackingPrior(growth_sd, sizing, tuple(estimated)), grid
    ll = grid.log_likelihood(evidence, sizing)
    mu, tau = estimate_growth_prior(ll, grid.z, informed)
    estimated = [*estimated, "growth_mean", "growth_sd"]
    return TrackingPrior(tau, sizing, tuple(estimated), growth_mean=mu), grid


# a tail whose posterior median lies this many of the fleet's sds from its mean is surprised:
# the fit of a fleet without scatter holds it at its own factor (fit_tracked)
SURPRISED = 4.0

# step in z of the finite difference that gives each prediction's sensitivity d ln a / dz
SENSITIVITY_STEP = 0.01

# alternations of the joint fit and the empirical-Bayes tau (measured on the fleet: a
# second one changed the year-5 errors and bands by < 0.3 points and costs a third of a retrain)
DEFAULT_ROUNDS = 1


@dataclass(frozen=True)
class InspectedTails:
    """What a joint fit marches: the rows with measured growth (InspectedTails.of), each twice (at z
    and at z + SENSITIVITY_STEP) as lanes of one march that ends at the last inspection (later
    flights say nothing here).  tails: (tails,) their evidence tail ids; row_tail: (rows,) each
    row's index into tails; observations index the rows."""

    tails: Tensor
    row_tail: Tensor
    observations: Observations
    stress: Tensor
    lengths: Tensor
    initial: Tensor

    @classmethod
    def of(cls, evidence: TailEvidence, law: ParisLaw) -> InspectedTails | None:
        """None where no measured crack lies below law.runaway_crack_m: a crack that ran away
        says the tail failed (its posterior keeps it) but nothing of the growth law."""
        obs = evidence.observations
        obs = obs.subset(obs.crack_length_m.double() < law.runaway_crack_m)
        if len(obs.aircraft) == 0:
            return None
        rows, local_row = torch.unique(obs.aircraft, return_inverse=True)
        tails, row_tail = torch.unique(evidence.row_tail[rows], return_inverse=True)
        local_obs = obs.subset(torch.arange(len(local_row)), local_row)
        loads = evidence.loads.select(rows).to(torch.float64).until(int(local_obs.flights.max()))
        return cls(
            tails,
            row_tail,
            local_obs,
            loads.stress_range_mpa.repeat(2, 1),
            loads.lengths.repeat(2),
            loads.initial_or(law.initial_crack_m).repeat(2),
        )

    def negative_log_marginal(
        self, model: CrackGrowthModel, z: Tensor, prior: TrackingPrior, mean: Tensor
    ) -> Tensor:
        """(tails,) -log of each tail's marginal likelihood, its z integrated out under its
        prior (model.tracking.surprise_prior about `mean`: N(mean, tau**2), a small share
        wide), by Laplace at z (exact at the tail's mode where its log posterior is
        quadratic): -l_i(z_i) - log p(z_i) + 0.5 log H_i (up to a constant), H_i the curvature
        of the log posterior in z_i, with ln a taken linear in z over one step either side."""
        rows, obs = len(self.row_tail), self.observations
        z_rows = z[self.row_tail]
        factors = torch.exp(torch.cat((z_rows, z_rows + SENSITIVITY_STEP)))
        points = (torch.cat((obs.aircraft, obs.aircraft + rows)), obs.flights.repeat(2))
        read = model(self.stress, self.lengths, self.initial, factors, at=points)
        log_a = torch.log(read[: len(obs.aircraft)].clamp_min(1e-12))
        shifted = torch.log(read[len(obs.aircraft) :].clamp_min(1e-12))
        slope = (shifted - log_a) / SENSITIVITY_STEP  # d ln a / dz of each observation
        steps = torch.tensor([0.0, -SENSITIVITY_STEP, SENSITIVITY_STEP], dtype=torch.float64)
        log_lik = observation_log_likelihood(
            torch.exp(log_a[:, None] + slope[:, None] * steps), obs, prior.sizing
        )
        per_tail = torch.zeros(len(self.tails), 3, dtype=torch.float64)
        per_tail = per_tail.index_add(0, self.row_tail[obs.aircraft], log_lik)
        information = (2 * per_tail[:, 0] - per_tail[:, 1] - per_tail[:, 2]) / SENSITIVITY_STEP**2
        log_prior, prior_curvature = surprise_prior(z - mean, max(prior.growth_sd, 1e-6))
        curvature = (information + prior_curvature).clamp_min(1e-12)
        return -per_tail[:, 0] - log_prior + 0.5 * torch.log(curvature / (2 * math.pi))


def fit_joint(
    model: CrackGrowthModel,
    evidence: TailEvidence,
    prior: TrackingPrior,
    start_z: Tensor,
    config: TrainConfig | None = None,
    progress: Callable[[float], None] | None = None,
) -> tuple[Tensor, FitResult]:
    """The shared weights and the fleet mean of z at the Laplace-approximate marginal
    likelihood, each inspected tail's z at its mode, at the prior's tau and sizing error (module docstring; the terms:
    InspectedTails.negative_log_marginal, which marches every inspected row twice); the model
    is fitted in place.  start_z: (tails,) where z starts.  Returns z (tails,) (the start for
    tails without inspections) and the fit's record; a fit that ends non-finite restores the
    weights it started from."""
    config = config or TrainConfig()
    inspected = InspectedTails.of(evidence, model.spec.law)
    if inspected is None:
        return start_z.clone().to(torch.float64), FitResult()
    z = torch.nn.Parameter(start_z[inspected.tails].clone().to(torch.float64))
    mean = torch.nn.Parameter(torch.tensor(prior.growth_mean, dtype=torch.float64))
    count = len(inspected.observations.aircraft)

    def loss_now() -> Tensor:
        return inspected.negative_log_marginal(model, z, prior, mean).sum() / count

    result = FitResult()
    before = {k: v.detach().clone() for k, v in model.state_dict().items()}
    weights = list(model.network_parameters().values())
    started = time.perf_counter()
    minimize_lbfgs([*weights, z, mean], loss_now, config, result, progress)
    result.seconds = time.perf_counter() - started
    out = start_z.clone().to(torch.float64)
    with torch.no_grad():
        result.final_loss = float(loss_now())
    if not (math.isfinite(result.final_loss) and all(bool(w.isfinite().all()) for w in weights)):
        model.load_state_dict(before)  # a diverged fit leaves the shared fit as it was
        return out, result
    out[inspected.tails] = z.detach()
    return out, result


@dataclass(frozen=True)
class TrackedFit:
    """What fit_tracked did: the fleet prior, each tail's growth posterior, the loads with each
    tail at its posterior mean factor, and the record of the last fit of the weights.  fresh:
    whether the posterior is the one growth_posterior(model, evidence, prior) computes anew (its
    grid was built under the prior's sizing error, not one estimated afterwards), so a caller
    that needs that one can take it instead of marching its grid again."""

    prior: TrackingPrior
    posterior: GrowthPosterior
    loads: LoadHistory
    result: FitResult
    fresh: bool = False


def fit_tracked(
    model: CrackGrowthModel,
    evidence: TailEvidence,
    sizing: SizingError,
    config: TrainConfig | None = None,
    *,
    rounds: int = DEFAULT_ROUNDS,
    growth_sd: float = 0.0,
    progress: Callable[[float], None] | None = None,
) -> TrackedFit:
    """The model's whole fit, with individual aircraft tracking.  model: as built
    (train.build_crack_model: a residual kernel starts at the physics).

    The fleet prior is read under the model as it is; where the fleet scatters
    (TrackingPrior.scatters), `rounds` joint fits of the weights and the tails' factors
    (fit_joint) alternate with the empirical-Bayes prior.  They start from the physics, not
    from a shared fit, which reads scatter as physics first: 2-3x faster, and on three seeds
    every tail that reaches a_crit flagged, against 8 of 12 on seed 1 (benchmarks/tracking.py;
    that seed's p95 error grew, see benchmarks/RESULTS.md).  Where the fleet does not scatter (the thesis's world, or
    after the joint fit says so), one shared fit with every tail at the fleet's rate, as before
    tracking existed (a tail whose own measurements surprised its prior at its own factor).  Then each tail's posterior.  Fits the model in place.  growth_sd: the
    fleet spread assumed where too few tails are inspected to learn it (fit_prior)."""
    evidence = replace(evidence, loads=model.loads_for(evidence.loads))
    grid_sizing = sizing  # the sizing error the latest grid was built under
    prior, grid = fit_prior(model, evidence, sizing, growth_sd=growth_sd)
    learned = bool(model.network_parameters())
    result = FitResult()
    for _ in range(rounds if learned and prior.scatters else 0):
        start = growth_posterior(model, evidence, prior, grid).mean()
        _, result = fit_joint(model, evidence, prior, start, config, progress)
        grid_sizing = prior.sizing
        prior, grid = fit_prior(model, evidence, prior.sizing, growth_sd=growth_sd)
        if not prior.scatters:
            break
    if learned and not prior.scatters:
        # the fleet's rate for every tail but one whose measurements its prior's surprise
        # share explains (its posterior median SURPRISED sds of the fleet's from the fleet's
        # mean), which keeps its own factor relative to the fleet's: one such crack (the demo's
        # 12.3 mm against 6.7) bent the shared kernel, and every later retrain was refused
        own = growth_posterior(model, evidence, prior, grid).quantiles([0.5])[:, 0]
        deviation = own - prior.growth_mean
        surprised = deviation.abs() > SURPRISED * max(prior.growth_sd, TAU_FLOOR)
        relative = torch.where(surprised, torch.exp(deviation), torch.ones_like(deviation))
        at_own = replace(evidence.loads, growth_factor=relative[evidence.row_tail])
        result = fit(model, at_own, evidence.observations, config, progress)
        grid_sizing = prior.sizing
        prior, grid = fit_prior(model, evidence, prior.sizing, growth_sd=growth_sd)
    if "growth_sd" in prior.estimated:
        prior = with_spread_posterior(prior, grid, evidence)
    posterior = growth_posterior(model, evidence, prior, grid)
    loads = replace(evidence.loads, growth_factor=torch.exp(posterior.mean())[evidence.row_tail])
    return TrackedFit(prior, posterior, loads, result, fresh=grid_sizing == prior.sizing)


def with_spread_posterior(
    prior: TrackingPrior, grid: Grid, evidence: TailEvidence
) -> TrackingPrior:
    """The prior with the fleet spread's posterior that every tail's prior mixes
    (model.tracking's module docstring): under the sizing error measured, or where nothing
    measured it, under each of SIZING_NODES relative sds of its prior about the stated one,
    each weighted by the prior's weight times the inspected tails' evidence under it.  A tail
    never inspected draws from the nodes' spreads together."""
    if "sizing_relative_sd" in prior.estimated:
        sds, weights = np.array([prior.sizing.relative_sd]), np.array([1.0])
    else:
        nodes, weights = np.polynomial.hermite_e.hermegauss(SIZING_NODES)
        sds = prior.sizing.relative_sd * np.exp(SIZING_PRIOR_SD * nodes)
        weights = weights / weights.sum()
    spreads, log_weights = [], []
    for sd, weight in zip(sds, weights, strict=True):
        sizing = replace(prior.sizing, relative_sd=float(sd))
        ll = grid.log_likelihood(evidence, sizing)
        spread, log_evidence = spread_with_evidence(
            ll, grid.z, evidence.informed, prior.growth_mean
        )
        spreads.append(spread)
        log_weights.append(math.log(weight) + log_evidence)
    posterior = np.exp(np.array(log_weights) - max(log_weights))
    posterior /= posterior.sum()
    nodes_out = tuple(
        SizingNode(float(sd), float(w), spread)
        for sd, w, spread in zip(sds, posterior, spreads, strict=True)
    )
    pooled = tuple(
        (tau, float(w) * tau_weight)
        for w, spread in zip(posterior, spreads, strict=True)
        for tau, tau_weight in spread
    )
    return replace(prior, uninspected_spread=pooled, sizing_nodes=nodes_out)
