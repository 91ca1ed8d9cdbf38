"""Probabilistic forecasts: quantile bands, P(critical), flights to critical and inspect-by,
sampled over a model's weight posterior (model.uncertainty), each tail's growth factor
(model.tracking) and future usage (model.forecast).

Forecast.  Sample k pairs parameter draw theta_k with future-load draw k (model.forecast's
ResampledLoads / PlannedLoads / FixedLoads), marches the tail's history (or starts at a given
crack) and then its future, and the quantiles, the probability of reaching a_crit and the
flights to a_crit are read across samples.  One compiled march per sample over all tails.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from model.forecast import FutureLoads
from model.hybrid import CrackGrowthModel
from model.integrate import LoadHistory, Observations
from model.path_drift import PathDrift
from model.train import non_detection_nll
from model.uncertainty import DEFAULT_NOISE_FLOOR, LaplacePosterior, flat_parameters

DEFAULT_SAMPLES = 200
QUANTILES = (0.05, 0.5, 0.95)
# lanes per compiled march where samples share their weights (here and model.fleet_sampling):
# bounds the stacked loads and trajectory at ~2 x lanes x flights x 8 B (120 MB at 7,300 flights)
LANES_PER_MARCH = 1024
# Where each sample carries its own growth factors (tails that scatter, model.tracking), sample k
# pairs weight draw k // WEIGHT_SHARING with factor draw k: the factors carry most of the spread,
# and samples that share their weights march together as lanes (one tail's update after an
# inspection, benchmarks/tracking_service.py: 1.50 s with 200 marches of its history, 0.31 s
# with 20 marches of 10 lanes each).
WEIGHT_SHARING = 10


def weight_draws(
    posterior: LaplacePosterior | None,
    theta: Tensor,
    samples: int,
    seed: int,
    shared: bool,
) -> Tensor:
    """(samples, parameters): sample k's weights, the fitted theta without a posterior; with
    `shared`, each draw serves WEIGHT_SHARING consecutive samples (module constant)."""
    if posterior is None:
        return theta.expand(samples, -1)
    if not shared:
        return posterior.sample(samples, seed)
    unique = -(-samples // WEIGHT_SHARING)
    return posterior.sample(unique, seed).repeat_interleave(WEIGHT_SHARING, dim=0)[:samples]


def sample_groups(samples: int, tails: int, posterior: bool, shared: bool) -> list[list[int]]:
    """The samples marched together (as lanes of one march): those that share their weights,
    at most LANES_PER_MARCH lanes of tails at a time.  A weight draw's samples go together only
    where they fit one march: for a fleet, one sample's tails already fill a march, and
    stacking its history again per sample only copies it."""
    per_march = max(1, LANES_PER_MARCH // max(tails, 1))
    block = samples
    if posterior:
        block = WEIGHT_SHARING if shared and per_march >= WEIGHT_SHARING else 1
    groups = []
    for first in range(0, samples, block):
        last = min(first + block, samples)
        groups += [list(range(k, min(k + per_march, last))) for k in range(first, last, per_march)]
    return groups


@dataclass(frozen=True)
class ProbabilisticForecast:
    """Sampled forecast of a batch of tails.  Flights count from each tail's forecast origin.

    report_flights: (points,) flight indices of the band points (0 = now); crack_p05_m,
    crack_p50_m, crack_p95_m: (tails, points) crack quantiles in m (a tail's points past its
    horizon repeat its crack at the horizon).  prob_critical: (tails,) share of samples that reach
    critical_crack_m within the tail's horizon.  flights_to_critical_p05/_p50/_p95: (tails,)
    quantiles of the flights until a_crit, inf where that quantile is not reached within the
    horizon.  inspect_by_flights: (tails,) the inspection interval of damage-tolerance practice
    (MIL-STD-1530C: half the time to critical), taken conservatively as half the p05 flights to
    critical, rounded down; inf where p05 lies beyond the horizon (then the interval is at least
    half the horizon); with a detectable crack given (the half-life rule), the p05 of each
    sample's midpoint between reaching it (now, where the crack already has) and reaching
    a_crit: half the crack's detectable life, counted from when it becomes detectable.
    samples: how many were drawn; effective_samples: (tails,) Kish effective count after
    weighting by `observations` (= samples without them).
    """

    report_flights: Tensor
    crack_p05_m: Tensor
    crack_p50_m: Tensor
    crack_p95_m: Tensor
    prob_critical: Tensor
    flights_to_critical_p05: Tensor
    flights_to_critical_p50: Tensor
    flights_to_critical_p95: Tensor
    inspect_by_flights: Tensor
    critical_crack_m: float
    samples: int
    effective_samples: Tensor


def weighted_quantiles(values: Tensor, weights: Tensor, quantiles: Sequence[float]) -> Tensor:
    """Quantiles over dim 0 of values (samples, ...) with weights (samples, tails) broadcast on the
    trailing dims: the smallest value whose cumulative weight reaches q.  Returns (q, ...).

    Where every sample weighs the same (no observations to weigh them by), the cumulative
    weight does not depend on the order, so the values are sorted without their order
    gathered (the same bits; a fleet's daily bands 2.5x faster)."""
    w = weights.reshape(weights.shape + (1,) * (values.dim() - weights.dim()))
    if weights.numel() and bool((weights == weights.reshape(-1)[0]).all()):
        ordered = torch.sort(values, dim=0).values
        column = w[(slice(None), *(slice(0, 1),) * (w.dim() - 1))]
        cumulative = column.cumsum(dim=0).expand(-1, *values.shape[1:])
    else:
        order = torch.argsort(values, dim=0)
        ordered = torch.gather(values, 0, order)
        cumulative = torch.gather(w.expand_as(values), 0, order).cumsum(dim=0)
    cumulative = cumulative / cumulative[-1:]
    out = []
    for q in quantiles:
        index = (cumulative < q - 1e-12).sum(dim=0, keepdim=True).clamp_max(values.shape[0] - 1)
        out.append(torch.gather(ordered, 0, index).squeeze(0))
    return torch.stack(out)


def _check_forecast_args(
    future: FutureLoads,
    crack_now_m: Tensor | None,
    history: LoadHistory | None,
    horizon_flights: Tensor | None,
    observations: Observations | None,
    samples: int,
) -> None:
    if (crack_now_m is None) == (history is None):
        raise ValueError("crack_now_m / history: give exactly one")
    tails = future.aircraft
    if crack_now_m is not None and crack_now_m.shape not in ((tails,), (samples, tails)):
        raise ValueError(
            f"crack_now_m must be ({tails},) or ({samples}, {tails}): per tail of `future`"
        )
    if history is not None and history.lengths.shape != (tails,):
        raise ValueError(f"history must hold {tails} aircraft, one per tail of `future`")
    if horizon_flights is not None and (
        horizon_flights.shape != (tails,)
        or int(horizon_flights.min()) < 0
        or int(horizon_flights.max()) > future.n_flights
    ):
        raise ValueError(f"horizon_flights must be ({tails},) in [0, {future.n_flights}]")
    if observations is not None and history is None:
        raise ValueError("observations need `history` (they are located on it)")
    if samples < 1:
        raise ValueError(f"samples must be >= 1, got {samples}")


def probabilistic_forecast(
    model: CrackGrowthModel,
    posterior: LaplacePosterior | None,
    future: FutureLoads,
    *,
    crack_now_m: Tensor | None = None,
    history: LoadHistory | None = None,
    horizon_flights: Tensor | None = None,
    samples: int = DEFAULT_SAMPLES,
    seed: int = 0,
    report_flights: Tensor | None = None,
    observations: Observations | None = None,
    growth_factor: Tensor | None = None,
    detectable_crack_m: float | None = None,
    drift: PathDrift | None = None,
) -> ProbabilisticForecast:
    """Quantile bands, P(a >= a_crit within the horizon), flights to a_crit and inspect-by.

    Sample k: theta_k from `posterior` (None: the model's own weights: usage uncertainty only),
    future stress ranges future.draw(k) (aircraft, flights) in MPa, the crack now either given
    (crack_now_m (tails,) m, e.g. a fresh inspection, or (samples, tails): sample k's own crack
    now, e.g. theta_k's march over the history, cached) or the march of theta_k over `history`
    (a LoadHistory of the same tails), then a_{t} = a_{t-1} + C max(dK_theta_k, 0)**m over the
    future flights, capped per tail at horizon_flights (tails,) (default: all).
    report_flights: (points,) flights at which to report the band (default: ~366 evenly spaced
    points from 0 to future.n_flights).  observations: inspections of the history the posterior
    has NOT been fitted on (e.g. recorded since); each sample is weighted by their likelihood
    (measured: ln a ~ N(ln a_pred, noise_sd**2); non-detection: P(not detected | a_pred)).
    growth_factor: each tail's growth-rate factor, (tails,) or sample k's own (samples, tails)
    (a tail's posterior, model.tracking); default the history's, else 1.  The history marches
    from its own initial cracks (repairs) where it sets them.  Where the model has an
    extrapolation (ModelSpec.extrapolation: the geometry factor's unknown trend beyond the
    measured cracks), sample k marches under its own slope of it; a given crack_now_m is read as
    already under it (as model.fleet_sampling.crack_samples gives it).  drift: each tail's path drift beyond
    its latest measurement (model.path_drift), on every point of sample k's forecast (the crack
    now included; marches start from the undrifted crack).  detectable_crack_m:
    inspect-by by the half-life rule (ProbabilisticForecast.inspect_by_flights; None: half the
    p05 flights to critical).
    Raises ValueError for inconsistent shapes, both or neither of crack_now_m / history,
    samples < 1, or a posterior of another model size.
    """
    if samples < 1:
        raise ValueError(f"samples must be >= 1, got {samples}")
    _check_forecast_args(future, crack_now_m, history, horizon_flights, observations, samples)
    theta = flat_parameters(model)
    if posterior is not None and posterior.parameters != theta.numel():
        raise ValueError(
            f"posterior has {posterior.parameters} parameters, the model {theta.numel()}"
        )
    law = model.spec.law
    tails, flights = future.aircraft, future.n_flights
    if growth_factor is None and history is not None:
        growth_factor = history.growth_factor
    shared = growth_factor is not None and growth_factor.dim() == 2
    draws = weight_draws(posterior, theta, samples, seed, shared)
    if report_flights is None:
        report_flights = torch.unique(
            torch.linspace(0, flights, min(flights + 1, 366)).round().long()
        )
    elif (
        report_flights.dim() != 1
        or int(report_flights.min()) < 0
        or int(report_flights.max()) > flights
    ):
        raise ValueError(f"report_flights must be 1-d flight indices in [0, {flights}]")
    horizon = (
        torch.full((tails,), flights, dtype=torch.long)
        if horizon_flights is None
        else horizon_flights
    )
    factors = _per_sample(growth_factor, samples, tails, "growth_factor")
    band = torch.empty(samples, tails, len(report_flights), dtype=torch.float32)
    to_critical = torch.empty(samples, tails, dtype=torch.float64)
    to_detectable = torch.zeros(samples, tails, dtype=torch.float64)
    log_weight = torch.zeros(samples, tails, dtype=torch.float64)
    critical = law.critical_crack_m
    extrapolation = model.spec.extrapolation
    eta = None if extrapolation is None else extrapolation.draws(samples, seed)
    with torch.no_grad():
        if history is not None:
            past = model.loads_for(history).to(torch.float64)
            start = past.initial_or(law.initial_crack_m)
        for ks in sample_groups(samples, tails, posterior is not None, shared):
            n = len(ks)
            factor = None if factors is None else factors[ks].reshape(-1)
            weights = draws[ks[0]]
            # sample k's shape of the extrapolation on each of its lanes (None: none)
            lane_eta = None if eta is None else eta[ks].repeat_interleave(tails, dim=0)
            if history is not None:
                lengths = past.lengths.repeat(n)
                traj = model.trajectory_with(
                    weights, past.stress_range_mpa.repeat(n, 1), lengths, start.repeat(n), factor
                )
                start_now = traj[torch.arange(n * tails), lengths]
                if observations is not None:
                    if extrapolation is not None and lane_eta is not None:
                        traj = extrapolation.beyond(traj, lane_eta)
                    for j, k in enumerate(ks):
                        lanes = traj[j * tails : (j + 1) * tails]
                        log_weight[k] = _log_likelihood(lanes, observations, posterior, tails)
            else:
                assert crack_now_m is not None
                now = torch.cat(
                    [(crack_now_m[k] if crack_now_m.dim() == 2 else crack_now_m) for k in ks]
                ).to(torch.float64)
                start_now = now
                if extrapolation is not None and lane_eta is not None:
                    start_now = extrapolation.within(now, lane_eta)
            stress = torch.from_numpy(
                np.concatenate([np.asarray(future.draw(k), dtype=np.float64) for k in ks])
            )
            traj = model.trajectory_with(weights, stress, horizon.repeat(n), start_now, factor)
            if extrapolation is not None and lane_eta is not None:
                traj = extrapolation.beyond(traj, lane_eta)
            if drift is not None:
                traj = drift.moved(traj, ks, law.held_crack_m)
            band[ks] = traj[:, report_flights].to(torch.float32).reshape(n, tails, -1)
            reached = traj >= critical
            first = reached.to(torch.int8).argmax(dim=1).to(torch.float64)
            hit = reached.any(dim=1) & (first <= horizon.repeat(n))
            reached_at = torch.where(hit, first, torch.full_like(first, math.inf))
            to_critical[ks] = reached_at.reshape(n, tails)
            if detectable_crack_m is not None:
                seen = traj >= detectable_crack_m
                found = seen.to(torch.int8).argmax(dim=1).to(torch.float64)
                found = torch.where(seen.any(dim=1), found, torch.full_like(found, math.inf))
                to_detectable[ks] = found.reshape(n, tails)
    weight = torch.exp(log_weight - log_weight.max(dim=0, keepdim=True).values)
    weight = weight / weight.sum(dim=0, keepdim=True)  # (samples, tails)
    crack_q = weighted_quantiles(band, weight.to(torch.float32), QUANTILES).to(torch.float64)
    flights_q = weighted_quantiles(to_critical, weight, QUANTILES)
    reached = torch.isfinite(to_critical)
    if observations is None:  # equal weights: a count, the same whatever tails come with it
        prob = reached.sum(dim=0).to(torch.float64) / samples
    else:  # a ratio of sums in one order: exactly 1 (or 0) when every sample (or none) reaches
        prob = (weight * reached).sum(dim=0) / weight.sum(dim=0)
    if detectable_crack_m is None:
        inspect_by = torch.floor(0.5 * flights_q[0])
    else:  # half-life: midway through each sample's detectable life, its p05
        midway = to_detectable + 0.5 * (to_critical - to_detectable)
        midway = torch.where(torch.isfinite(to_critical), midway, math.inf)
        inspect_by = torch.floor(weighted_quantiles(midway, weight, (0.05,))[0])
    return ProbabilisticForecast(
        report_flights=report_flights,
        crack_p05_m=crack_q[0],
        crack_p50_m=crack_q[1],
        crack_p95_m=crack_q[2],
        prob_critical=prob,
        flights_to_critical_p05=flights_q[0],
        flights_to_critical_p50=flights_q[1],
        flights_to_critical_p95=flights_q[2],
        inspect_by_flights=inspect_by,
        critical_crack_m=critical,
        samples=samples,
        effective_samples=1.0 / (weight**2).sum(dim=0),
    )


def _per_sample(values: Tensor | None, samples: int, tails: int, name: str) -> Tensor | None:
    """values (tails,) or (samples, tails) as (samples, tails) float64; None stays None."""
    if values is None:
        return None
    if values.shape == (tails,):
        return values.to(torch.float64).expand(samples, -1)
    if values.shape != (samples, tails):
        raise ValueError(f"{name} must be ({tails},) or ({samples}, {tails})")
    return values.to(torch.float64)


def _log_likelihood(
    trajectory: Tensor, observations: Observations, posterior: LaplacePosterior | None, tails: int
) -> Tensor:
    """Per-tail log-likelihood (tails,) of `observations` given one sample's history march."""
    sd = posterior.noise_sd if posterior is not None else DEFAULT_NOISE_FLOOR
    predicted = trajectory[observations.aircraft, observations.flights]
    n = len(predicted)
    hit = observations.measured
    term = torch.zeros(n, dtype=torch.float64)
    observed = observations.crack_length_m.to(torch.float64)
    term[hit] = -0.5 * ((torch.log(observed[hit]) - torch.log(predicted[hit])) / sd) ** 2
    if not bool(hit.all()):
        assert observations.detection_a50_m is not None
        missed = ~hit
        a90 = None if observations.detection_a90_m is None else observations.detection_a90_m[missed]
        term[missed] = -non_detection_nll(
            predicted[missed], observations.detection_a50_m[missed].double(), a90, sd
        )
    out = torch.zeros(tails, dtype=torch.float64)
    return out.index_add_(0, observations.aircraft, term)
