"""Learning the growth law's C and m (and Walker's gamma) from a fleet's inspections, so that a fleet of another alloy needs no
hand-tuned constants.

Why a separate, physics-only step before the network.  The residual kernel corrects dK by a
factor (1 + MLP) that is meant to stay near one: it learns what Paris' law misses (a geometry
factor, a load interaction), not an order of magnitude of C or a wrong exponent, which it can
only approximate inside its input box and which then leaks into every extrapolation.  So the
law is fitted first to the same likelihood the joint fit uses (log-normal sizing error,
non-detections through the PoD curve, model.tracking), each inspected tail with its own growth
factor z, so that tail-to-tail scatter is not read as a different m;
the network then fits what remains (model.tracking_fit).

The physics alone has a closed form for any load sequence: with p = 1 - m/2, integrating
da/dN = C e**z (F dS sqrt(pi a))**m over flights gives
    a_k**p = a_0**p + p C e**z (F sqrt(pi))**m S_k,   S_k = sum of dS**m over the first k flights,
exact in the limit of small growth per flight (the march's Euler step; growth per flight is
below 1e-3 of the crack short of a_crit).  So each evaluation is a cumulative sum over the
flights, and C, m and every z are fitted by L-BFGS through autograd in seconds.  Where the
flights were recorded as cycles, dS**m is each flight's damage under the law (the sum over its
cycles of n (dS (1 - R)**(gamma - 1))**m, model.growth_laws), so Walker's gamma is fitted with
C and m; a fleet recorded as one range per flight carries no load ratio and keeps its gamma.

Where the law has a geometry table, F(a) varies over the growth and the closed form above
does not hold: the crack then solves H(a) - H(a0) = C e**z S_k with H the integral of
da / (F(a) sqrt(pi a))**m (model.growth_integral), so the table is counted once, in H, and
the fitted C and m are the material's.  (Holding F at its a0 value instead made C and m absorb
the table's rise, which the march then applied again.)
"""

from __future__ import annotations

import math
from dataclasses import replace

import torch
from torch import Tensor

from model.binned_damage import bin_cycles, cumulative_at, stretches
from model.growth_integral import log_integral_grid, table_log_crack
from model.growth_laws import GROWTH_LAWS, fixed_below_zero
from model.physics import ParisLaw
from model.tracking import MAX_GROWTH_SD, SizingError, TailEvidence
from model.tracking_fit import MIN_SIZING_DOF
from model.tracking_grid import observation_log_likelihood
from model.train import FitResult, TrainConfig, minimize_lbfgs

# Exponents outside this range are not a metal's Paris regime: a fit that ends there (too few
# crack sizes to tell m from C) keeps the configured m and fits C alone.
PLAUSIBLE_M = (1.5, 8.0)
MIN_CALIBRATION_TAILS = 2


def physics_log_crack(
    log_a0: Tensor, log_rate: Tensor, m: Tensor, cumulative_load: Tensor, held_crack_m: float
) -> Tensor:
    """ln a after the flights summed in cumulative_load (S_k, module docstring), from
    ln a0, ln(C e**z (F sqrt(pi))**m) and m, all broadcast together; held at held_crack_m
    past fracture.  Written as ln a0 + log1p(u) / p with u = p rate S a0**-p, which stays exact
    as m -> 2 (p -> 0, where it tends to the exponential law's rate S)."""
    p = 1.0 - 0.5 * m
    growth = torch.exp(log_rate - p * log_a0) * cumulative_load  # rate S a0**-p
    near_two = p.abs() < 1e-6
    safe_p = torch.where(near_two, torch.ones_like(p), p)
    u = (safe_p * growth).clamp_min(-1.0 + 1e-12)  # u -> -1: the crack diverges
    log_a = log_a0 + torch.where(near_two, growth, torch.log1p(u) / safe_p)
    return log_a.clamp_max(math.log(held_crack_m))


def _cumulative_load(stress: Tensor, m: Tensor) -> Tensor:
    """S_k = sum_{t<k} dS_t**m (rows, flights + 1) of each row of `stress` (rows, flights)."""
    powered = torch.where(stress > 0, torch.exp(m * torch.log(stress.clamp_min(1e-300))), 0.0)
    return torch.cat((torch.zeros_like(powered[:, :1]), powered.cumsum(dim=1)), dim=1)


# Walker's gamma is fitted as sigmoid(u) in (0, 1), from at most this far inside the interval
_GAMMA_START = (0.05, 0.95)


# alternations of the fit and the sizing sd of its residuals
CALIBRATION_ROUNDS = 3
# L-BFGS iterations of a calibration (each costs one cumulative sum over the flights)
CALIBRATION_ITERATIONS = 200


def calibrate_law(
    evidence: TailEvidence,
    law: ParisLaw,
    sizing: SizingError,
    *,
    learn_m: bool = True,
    growth_law: str = "paris",
) -> tuple[ParisLaw, FitResult]:
    """Paris C (and m) fitted to the inspections by the physics alone (module docstring),
    starting from `law`, whose geometry (its factor, or its table read at every crack),
    initial and critical crack are kept.  Measured
    cracks that ran away (ParisLaw.runaway_crack_m) are left out.  With inspections of
    fewer than MIN_CALIBRATION_TAILS tails, or a fit that ends non-finite, `law` is returned
    unchanged; an m outside PLAUSIBLE_M is refitted with m held.  Measurements before any
    flight are left out too.  Returns the law and the record
    of its last fit.

    C and m trade off almost exactly (a larger m with a smaller C grows the same near the data),
    so the fit runs over m and q = ln(C K_ref**m), the log growth per flight at a reference
    dK_ref of the data (median load, geometric-mean measured crack), which are nearly
    independent.  Raises ValueError for a law it cannot fit (GrowthLaw.calibrated)."""
    if not GROWTH_LAWS[growth_law].calibrated:
        raise ValueError(
            f"growth law {growth_law!r} is not calibrated from inspections: its constants come "
            "from the materials table (learn_paris takes paris or walker)"
        )
    obs = evidence.observations
    # a measurement before any flight is the initial crack, which the law holds exactly: it says
    # nothing of C and m (kept, it made the fit overflow where every tail was measured at flight
    # 0 and once more: alloy-A's refits with the notch measured at cycle 0)
    obs = obs.subset((obs.crack_length_m.double() < law.runaway_crack_m) & (obs.flights > 0))
    rows, local_row = torch.unique(obs.aircraft, return_inverse=True)
    tails, row_tail = torch.unique(evidence.row_tail[rows], return_inverse=True)
    if len(tails) < MIN_CALIBRATION_TAILS:
        return law, FitResult()
    loads = evidence.loads.select(rows).to(torch.float64)
    stress = loads.for_law(growth_law, law.constants).stress_range_mpa
    cycles = loads.cycles
    if cycles is not None and GROWTH_LAWS[growth_law].uses_gamma:
        cycles = fixed_below_zero(cycles, law.constants)  # their gamma is not learned
    rule = GROWTH_LAWS[growth_law]
    learn_gamma = rule.uses_gamma and cycles is not None
    binned = None
    if cycles is not None:
        bounds = stretches(local_row.numpy(), obs.flights.numpy(), len(rows), stress.shape[1])
        binned = bin_cycles(cycles, bounds[0], int(bounds[0].max(initial=-1)) + 1)
        first, ends = torch.from_numpy(bounds[1]), torch.from_numpy(bounds[2])
    log_a0 = torch.log(loads.initial_or(law.initial_crack_m).double())[local_row]
    flights = obs.flights
    tail_of_obs = row_tail[local_row]
    log_shape = math.log(law.geometry_factor * math.sqrt(math.pi))  # ln(F(a0) sqrt(pi))
    table = law.geometry_table
    smallest_crack_m = 0.999 * float(torch.exp(log_a0.min())) if len(log_a0) else 1.0
    flown = stress[stress > 0]
    measured = obs.crack_length_m[obs.measured].double()
    measured = measured[measured > 0]
    typical_crack = float(torch.log(measured).mean()) if len(measured) else float(log_a0.mean())
    log_k_ref = log_shape + math.log(float(flown.median())) + 0.5 * typical_crack
    config = TrainConfig(lbfgs_iterations=CALIBRATION_ITERATIONS)

    hit = obs.measured
    repeated_dof = len(flights) - len(tails) - 2

    # The tails' factors get a weak N(0, MAX_GROWTH_SD**2) prior: it only ties their mean to
    # C.  A tighter one (the fleet's spread, re-estimated from the fitted factors) shrank them,
    # and the common curve then bent m (alloy-A, measured while developing it: m 5.0 against the
    # per-specimen fits' 4.0); empirical Bayes proper follows in the tracking fit.
    precision = 1.0 / MAX_GROWTH_SD**2

    def fit_once(m_free: bool, sizing: SizingError) -> tuple[ParisLaw, FitResult, float]:
        q = torch.nn.Parameter(torch.tensor(math.log(law.c) + law.m * log_k_ref).double())
        m = torch.nn.Parameter(torch.tensor(law.m, dtype=torch.float64), requires_grad=m_free)
        z = torch.nn.Parameter(torch.zeros(len(tails), dtype=torch.float64))
        start = min(max(law.gamma, _GAMMA_START[0]), _GAMMA_START[1])
        u = torch.nn.Parameter(torch.tensor(math.log(start / (1.0 - start))).double())

        def damage() -> Tensor:
            """(observations,) S_k of each observation."""
            if binned is None:
                return _cumulative_load(stress, m)[local_row, flights]
            gamma = (
                torch.sigmoid(u) if learn_gamma else torch.tensor(law.gamma, dtype=torch.float64)
            )
            return cumulative_at(binned(m, gamma, rule.uses_gamma), first, ends, local_row)

        def log_crack() -> Tensor:
            cumulative = damage()
            if table is not None:  # F(a) inside H: the table counted once (growth_integral)
                grid = log_integral_grid(table, m, smallest_crack_m, law.held_crack_m)
                log_rate = q - m * log_k_ref + z[tail_of_obs]
                return table_log_crack(log_a0, log_rate, cumulative, grid)
            log_rate = q - m * log_k_ref + m * log_shape + z[tail_of_obs]
            return physics_log_crack(log_a0, log_rate, m, cumulative, law.held_crack_m)

        def loss() -> Tensor:
            log_lik = observation_log_likelihood(torch.exp(log_crack())[:, None], obs, sizing)
            return (0.5 * precision * (z**2).sum() - log_lik.sum()) / len(flights)

        result = FitResult()
        free = [q, m, z] if m_free else [q, z]
        minimize_lbfgs([*free, u] if learn_gamma else free, loss, config, result)
        with torch.no_grad():
            residual = torch.log(obs.crack_length_m.double()[hit]) - log_crack()[hit]
        sizing_sd = math.sqrt(float(residual.pow(2).sum()) / max(repeated_dof, 1))
        fitted_m = float(m.detach())
        c = math.exp(float(q.detach()) - fitted_m * log_k_ref)
        gamma = float(torch.sigmoid(u.detach())) if learn_gamma else law.gamma
        if not (math.isfinite(c) and c > 0 and math.isfinite(fitted_m) and fitted_m > 0):
            return law, result, sizing_sd
        if not math.isfinite(gamma):
            return law, result, sizing_sd
        return replace(law, c=c, m=fitted_m, gamma=gamma), result, sizing_sd

    # alternate the fit with the relative sizing sd of its residuals (given enough repeated
    # measurements): an assumed sd far above the data's lets the prior on z outweigh the
    # measurements, and m bends again (alloy-A, measured while developing it: m 9.6 at the
    # default 5 %, 4.0 at the data's 0.5 %)
    fitted, result = law, FitResult()
    for _ in range(CALIBRATION_ROUNDS):
        fitted, result, sizing_sd = fit_once(learn_m, sizing)
        if repeated_dof >= MIN_SIZING_DOF and math.isfinite(sizing_sd):
            sizing = replace(sizing, relative_sd=max(sizing_sd, 1e-4))
    if learn_m and not PLAUSIBLE_M[0] <= fitted.m <= PLAUSIBLE_M[1]:
        fitted, result, _ = fit_once(False, sizing)
    return fitted, result
