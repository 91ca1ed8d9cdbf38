"""Growth that drifts along a crack's path (model.path_variability)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from model.fleet import FleetConfig, generate_fleet, inspect_at
from model.hybrid import CrackGrowthModel, ModelSpec
from model.integrate import LoadHistory, Observations
from model.path_drift import PathDrift, latest_measured, moved_log_growth, wander
from model.path_variability import (
    MAX_REFIT_TAILS,
    FittedForTracking,
    _drift_fit,
    earlier_repeats,
    estimate_path_sd,
    refit_sample,
    split_measurements,
)
from model.tracking import SizingError, TailEvidence, TrackingPrior


def _drifted(growth: np.ndarray, path_sd: float, rng: np.random.Generator) -> np.ndarray:
    """Each log growth's move by its own drift draw (model.path_drift), less the growth."""
    z = rng.normal(size=len(growth))
    return np.array([moved_log_growth(d, path_sd * c) - d for d, c in zip(growth, z, strict=True)])


def test_the_drift_posterior_recovers_a_known_drift():
    rng = np.random.default_rng(0)
    growth = rng.uniform(0.05, 0.6, 400)
    variance = rng.uniform(1e-4, 4e-4, 400)
    for true_sd in (0.0, 0.3, 1.0, 2.0):
        residual = _drifted(growth, true_sd, rng) + rng.normal(size=400) * np.sqrt(variance)
        assert abs(_drift_fit(residual, variance, growth).path_sd - true_sd) < 0.1 * true_sd + 0.03


def test_a_drift_moves_every_path_on_to_a_crit():
    """The drift is symmetric in its draws, not in the log: the upward draw z moves the log
    growth d to d + c d**2 (c = path_sd z) and -z takes that back to d, so every drawn path keeps
    growing and crosses a_crit once its march does.  d + c d**2 for both signs turned over past
    d = 1 / (2 |c|): at path_sd 1.6 and a_crit 1.42 x the latest measurement (Hudak's alloy-A
    at 40,000 cycles) a third of the draws never reached a_crit, however long the horizon."""
    for c in (0.3, 1.6, 5.0):
        for d in (0.05, 0.35, 2.0):
            up = moved_log_growth(d, c)
            assert up == pytest.approx(d + c * d**2)
            assert moved_log_growth(up, -c) == pytest.approx(d)
    samples, since, critical = 4000, torch.tensor([0.01], dtype=torch.float64), 0.0142
    path = torch.logspace(-2, math.log10(0.142), 200, dtype=torch.float64)[None]  # to 10 a_crit
    drift = PathDrift.drawn(1.6, since, samples, seeds=[3])
    moved = drift.moved(path.repeat(samples, 1), list(range(samples)), held_m=0.142)
    assert bool(torch.all(torch.diff(moved, dim=1) >= 0))  # every path grows
    assert bool(torch.all(moved[:, -1] >= critical))  # and reaches a_crit
    near = path[0] <= 0.02  # where the median draw's sampling error moves little
    median = moved[:, near].median(dim=0).values
    torch.testing.assert_close(median, path[0, near], rtol=0.03, atol=0)  # the p50 stays put


def test_short_held_out_growth_leaves_the_drift_open_not_zero():
    """Held-out growth of a few percent in the log (Hudak's deeply inspected specimens): a drift
    of 1 adds 1e-6 to a variance of 2.5e-5 there, so the likelihood's maximum may sit at 0, but
    the data do not rule out a drift that matters at a forecast's 0.4 (its posterior)."""
    rng = np.random.default_rng(1)
    growth = rng.uniform(0.01, 0.05, 40)
    variance = np.full(40, 2.5e-5)
    residual = rng.normal(size=40) * np.sqrt(variance) * 0.8  # a little tighter than predicted
    fit = _drift_fit(residual, variance, growth)
    at_zero = float(-0.5 * np.sum(residual**2 / variance + np.log(2 * math.pi * variance)))
    assert fit.held_out_log_likelihood == pytest.approx(at_zero, abs=0.01)  # the maximum: none
    assert fit.path_sd > 0.5  # 8 % in the log at d = 0.4


def test_a_fleet_without_drift_gets_none():
    """Tails that grow at one factor for life (the generator's), refitted as the true physics
    and prior: each tail's later measurements are as its earlier ones say."""
    fleet = generate_fleet(FleetConfig(aircraft_per_mix=10, years=3, growth_scatter=0.25, seed=4))
    fpy = fleet.config.flights_per_year
    sample = inspect_at(fleet, np.arange(fleet.size), np.array([fpy, 2 * fpy, 3 * fpy]), 0.03, 4)
    stress = torch.from_numpy(fleet.stress_range_mpa)
    loads = LoadHistory(stress, torch.full((fleet.size,), stress.shape[1]))
    evidence = TailEvidence(loads, torch.arange(fleet.size), sample.observations, fleet.size)
    prior = TrackingPrior(0.25, SizingError(0.03, 1e-6))
    physics = CrackGrowthModel(ModelSpec(kernel="physics", law=fleet.config.law))
    refits = []

    def refit(earlier: TailEvidence) -> FittedForTracking:
        refits.append(len(earlier.observations.aircraft))
        return FittedForTracking(physics, None, prior)

    fit = estimate_path_sd(refit, evidence, fleet.config.law.critical_crack_m)
    # the refit saw each tail's earlier half: 2 of its 3 measurements below a_crit
    assert refits and refits[0] < len(sample.observations.aircraft)
    # what it adds over half a log unit of extrapolation is within twice the sizing noise (the
    # posterior mean: 0.20 here; the downward half of the drift bounds s less than the upward)
    assert fit.held_out_log_likelihood is not None and fit.path_sd * 0.5**2 < 0.06


def test_wander_widens_with_the_growth_since_the_latest_measurement():
    """Its upper half moves the log growth d by 0.3 d**2 z: the 84th percentile by 0.3 d**2."""
    cracks = torch.tensor([[0.01, 0.02, 0.04]], dtype=torch.float64).expand(4000, -1)
    since = torch.tensor([0.01, 0.01, 0.01], dtype=torch.float64)
    assert torch.equal(wander(cracks, since, 0.0), cracks)
    moved = torch.log(wander(cracks, since, 0.3) / cracks)
    upper = torch.quantile(moved, 0.8413, dim=0)
    expected = 0.3 * torch.log(cracks[0] / since) ** 2
    torch.testing.assert_close(upper, expected, atol=0.01, rtol=0.05)


def test_each_origin_keeps_its_share_of_every_tails_measurements():
    """Six measurements: the first third keeps two and holds four out, each predicted from the
    second; the first half keeps three.  Two measurements: both keep the first."""
    flights = [100, 200, 300, 400, 500, 600, 150, 250]
    rows = [0, 0, 0, 0, 0, 0, 1, 1]
    obs = Observations(
        torch.tensor(rows), torch.tensor(flights), torch.linspace(0.006, 0.02, 8).double()
    )
    loads = LoadHistory(torch.full((2, 700), 80.0, dtype=torch.float64), torch.tensor([700, 700]))
    evidence = TailEvidence(loads, torch.arange(2), obs, 2)
    held, previous, kept = split_measurements(evidence, 0.05, 1 / 3)
    assert held.tolist() == [2, 3, 4, 5, 7] and previous.tolist() == [1, 1, 1, 1, 6]
    assert kept.tolist() == [True, True, False, False, False, False, True, False]
    held, previous, _ = split_measurements(evidence, 0.05, 1 / 2)
    assert held.tolist() == [3, 4, 5, 7] and previous.tolist() == [2, 2, 2, 6]


def test_the_refits_read_a_seeded_sample_of_the_inspected_tails_with_all_their_rows() -> None:
    """Eight tails (tail 2 repaired: two rows), six inspected; a limit of three keeps three
    inspected tails with every row and measurement of each, re-indexed from 0, the same three
    every time; a limit of six keeps the evidence as it is."""
    row_tail = torch.tensor([0, 1, 2, 2, 3, 4, 5, 6, 7])
    lengths = torch.arange(1, 10) * 10
    loads = LoadHistory(
        torch.arange(1.0, 10.0, dtype=torch.float64)[:, None].expand(9, 100).contiguous(),
        lengths,
    )
    measured_rows = [0, 2, 3, 3, 4, 6, 8]  # tails 0, 2, 2, 2, 3, 5, 7
    obs = Observations(
        torch.tensor(measured_rows),
        lengths[measured_rows] - 1,
        torch.linspace(0.006, 0.02, 7).double(),
    )
    evidence = TailEvidence(loads, row_tail, obs, 8)
    assert refit_sample(evidence, limit=6) is evidence
    sample = refit_sample(evidence, limit=3)
    assert sample.tails == 3 and bool(sample.informed.all())
    again = refit_sample(evidence, limit=3)
    assert torch.equal(again.loads.stress_range_mpa, sample.loads.stress_range_mpa)
    # every row of a kept tail comes along, its loads and measurements with it
    stress = sample.loads.stress_range_mpa[:, 0].long().tolist()
    kept_tails = {int(row_tail[s - 1]) for s in stress}
    assert len(kept_tails) == 3
    assert len(stress) == sum(int((row_tail == t).sum()) for t in kept_tails)
    for k, row in enumerate(sample.observations.aircraft.tolist()):
        original = stress[row] - 1  # the loads' row in the evidence
        assert int(sample.observations.flights[k]) == int(lengths[original]) - 1
    assert sample.row_tail.tolist() == sorted(sample.row_tail.tolist())


def test_a_path_drifts_along_the_whole_forecast_as_wander_moves_its_crack_now() -> None:
    """PathDrift.moved is `wander` at every point of a sampled path, with one draw per sample and
    tail: the same spread as wander's at the same growth, none below the latest measurement,
    a held crack stays held, and a tail's drift does not depend on the tails beside it."""
    samples, since = 4000, torch.tensor([0.01, 0.02], dtype=torch.float64)
    drift = PathDrift.drawn(0.3, since, samples, seeds=[11, 12])
    path = torch.tensor([[0.005, 0.01, 0.02, 0.04, 0.5]], dtype=torch.float64)
    lanes = path.repeat(samples * 2, 1)  # sample-major: sample k's two tails
    moved = drift.moved(lanes, list(range(samples)), held_m=0.5).view(samples, 2, -1)
    first = moved[:, 0]
    assert torch.equal(first[:, :2], path[:, :2].expand(samples, -1))  # at or below since
    assert torch.all(first[:, -1] == 0.5)  # held
    spread = torch.quantile(torch.log(first[:, 3] / 0.04), 0.8413)
    assert float(spread) == pytest.approx(0.3 * math.log(4) ** 2, rel=0.05)
    reference = wander(torch.full((samples, 1), 0.04), since[:1], 0.3).log().sub(math.log(0.04))
    assert float(spread) == pytest.approx(float(torch.quantile(reference, 0.8413)), rel=0.05)
    alone = PathDrift.drawn(0.3, since[:1], samples, seeds=[11])
    solo = alone.moved(path.repeat(samples, 1), list(range(samples)), held_m=0.5)
    assert torch.equal(solo, moved[:, 0])


def test_a_tail_never_measured_drifts_from_the_fleets_longest_measured_crack() -> None:
    """Up to the cracks the fleet measured, the fleet's law and spread carry a tail never
    inspected; its drift starts beyond them (or at its own initial crack where that is
    longer), an inspected tail's at its own latest measurement."""
    loads = LoadHistory(
        torch.full((3, 10), 80.0),
        torch.full((3,), 10),
        initial_crack_m=torch.tensor([0.005, 0.005, 0.03], dtype=torch.float64),
    )
    measured = Observations(
        torch.tensor([0, 0]), torch.tensor([4, 8]), torch.tensor([0.006, 0.007])
    )
    since = latest_measured(loads, measured, 0.005, fleet_measured_m=0.02)
    assert since.tolist() == pytest.approx([0.007, 0.02, 0.03])
    assert latest_measured(loads, measured, 0.005).tolist() == pytest.approx([0.007, 0.005, 0.03])


def test_the_kernels_are_compared_on_what_the_refits_read() -> None:
    """earlier_repeats asks of the tails the refits read (refit_sample): a tail measured four
    times outside that sample does not make a comparison of refits that never hold it."""
    tails = MAX_REFIT_TAILS + 20
    loads = LoadHistory(torch.full((tails, 400), 80.0), torch.full((tails,), 400))

    def evidence(repeated: int) -> TailEvidence:
        rows = [(i, f) for i in range(tails) for f in (100, 200)]
        rows += [(repeated, f) for f in (300, 400)]
        aircraft, flights = (torch.tensor(column) for column in zip(*rows, strict=True))
        cracks = 0.005 + 1e-5 * flights.double()
        observations = Observations(aircraft, flights, cracks)
        return TailEvidence(loads, torch.arange(tails), observations, tails)

    sampled = refit_sample(evidence(0))
    read = set(sampled.row_tail.tolist())
    chosen = np.sort(np.random.default_rng(0).choice(tails, MAX_REFIT_TAILS, replace=False))
    outside = next(i for i in range(tails) if i not in set(chosen.tolist()))
    inside = int(chosen[0])
    assert len(read) == MAX_REFIT_TAILS
    assert earlier_repeats(evidence(inside), 0.05)
    assert not earlier_repeats(evidence(outside), 0.05)
