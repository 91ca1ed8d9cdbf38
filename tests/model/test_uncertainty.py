import math
from dataclasses import replace

import numpy as np
import pytest
import torch

from model import artifacts
from model.cells import DamageCell, DamageKernel, InputBox, PhysicsKernel
from model.fast_march import fast_march
from model.fleet import FleetConfig, generate_fleet
from model.forecast import FixedLoads, PlannedLoads, PlannedUtilization, ResampledLoads
from model.hybrid import CrackGrowthModel, ModelSpec
from model.integrate import LoadHistory, Observations
from model.physics import ParisLaw, stress_intensity_range
from model.prognosis import probabilistic_forecast, weighted_quantiles
from model.train import TrainConfig, fit, fit_crack_model, observation_loss
from model.uncertainty import LaplacePosterior, flat_parameters
from model.uncertainty_fit import laplace_posterior, log_crack_jacobian

# One year of a small, fast-growing fleet (larger Paris C) with a crack-length discrepancy:
# data end after 9 months, 10 tails are inspected then, forecasts cover the last 3 months.
LAW = ParisLaw(c=6e-11)
NOW, AHEAD = 1095, 365


@pytest.fixture(scope="module")
def scenario():
    torch.set_num_threads(1)
    fleet = generate_fleet(
        FleetConfig(aircraft_per_mix=15, years=1, discrepancy=0.1, law=LAW, seed=3)
    )
    n = fleet.size
    truth = fleet.crack_length_m
    rng = np.random.default_rng(0)
    inspected = np.sort(rng.choice(n, 10, replace=False))
    history = LoadHistory(
        torch.from_numpy(fleet.stress_range_mpa[:, :NOW].copy()), torch.full((n,), NOW)
    )
    sub = history.select(torch.from_numpy(inspected))
    obs = Observations(
        torch.arange(10), torch.full((10,), NOW), torch.from_numpy(truth[inspected, NOW].copy())
    )
    model, _ = fit_crack_model(sub, obs, law=LAW)
    posterior = laplace_posterior(model, sub, obs)
    recent = [fleet.stress_range_mpa[i, NOW - 365 : NOW] for i in range(n)]
    future = ResampledLoads(recent, AHEAD, seed=0)
    return fleet, inspected, history, sub, obs, model, posterior, future


def test_bands_cover_the_truth_of_uninspected_tails(scenario):
    fleet, inspected, history, _, _, model, posterior, future = scenario
    forecast = probabilistic_forecast(
        model, posterior, future, history=history, samples=100, seed=0
    )
    truth = fleet.crack_length_m[:, NOW + AHEAD]
    assert int(forecast.report_flights[-1]) == AHEAD
    p05, p50, p95 = (
        q[:, -1].numpy() for q in (forecast.crack_p05_m, forecast.crack_p50_m, forecast.crack_p95_m)
    )
    uninspected = np.ones(fleet.size, dtype=bool)
    uninspected[inspected] = False
    assert uninspected.sum() == 35
    below = uninspected & (truth < LAW.critical_crack_m)
    covered = ((truth >= p05) & (truth <= p95))[below].mean()
    assert covered >= 0.85
    assert np.median(np.abs(p50 / truth - 1)[below]) < 0.01
    assert np.median(((p95 - p05) / truth)[below]) < 0.05
    # quantiles are ordered and the probability is a probability
    assert bool((forecast.crack_p05_m <= forecast.crack_p50_m).all())
    assert bool((forecast.crack_p50_m <= forecast.crack_p95_m).all())
    assert bool(((forecast.prob_critical >= 0) & (forecast.prob_critical <= 1)).all())


def test_time_to_critical_and_inspect_by_follow_the_samples():
    # physics kernel, constant stress: a tail at 0.04 m reaches 0.05 m within its horizon, one
    # at 0.006 m not within its 50 flights
    model, _ = fit_crack_model(
        LoadHistory.from_sequences([[120.0] * 10]),
        Observations(torch.tensor([0]), torch.tensor([10]), torch.tensor([0.005])),
        kernel="physics",
        law=LAW,
    )
    future = FixedLoads(np.full((2, 4000), 120.0))
    forecast = probabilistic_forecast(
        model,
        None,
        future,
        crack_now_m=torch.tensor([0.04, 0.006]),
        horizon_flights=torch.tensor([4000, 50]),
        samples=3,
    )
    crack = torch.tensor([0.04])
    flights = 0
    while float(crack) < LAW.critical_crack_m:  # the Euler recurrence by hand
        crack = crack + LAW.c * (120.0 * torch.sqrt(torch.pi * crack)) ** LAW.m
        flights += 1
    assert forecast.prob_critical.tolist() == [1.0, 0.0]
    assert float(forecast.flights_to_critical_p50[0]) == flights
    assert float(forecast.inspect_by_flights[0]) == flights // 2
    assert forecast.flights_to_critical_p05[1] == float("inf")
    assert forecast.inspect_by_flights[1] == float("inf")


def test_the_half_life_rule_inspects_midway_through_the_detectable_life():
    """Inspect-by by the damage-tolerance half-life rule: a crack already detectable is
    inspected by half its flights to critical (the default rule's answer); one not yet
    detectable by the midpoint between reaching the detectable size and a_crit."""
    model, _ = fit_crack_model(
        LoadHistory.from_sequences([[120.0] * 10]),
        Observations(torch.tensor([0]), torch.tensor([10]), torch.tensor([0.005])),
        kernel="physics",
        law=LAW,
    )
    detectable = 0.03

    def flights_to(start: float, size: float) -> int:
        crack, flights = torch.tensor([start]), 0
        while float(crack) < size:  # the Euler recurrence by hand
            crack = crack + LAW.c * (120.0 * torch.sqrt(torch.pi * crack)) ** LAW.m
            flights += 1
        return flights

    forecast = probabilistic_forecast(
        model,
        None,
        FixedLoads(np.full((2, 20000), 120.0)),
        crack_now_m=torch.tensor([0.04, 0.02]),
        samples=3,
        detectable_crack_m=detectable,
    )
    critical = LAW.critical_crack_m
    assert float(forecast.inspect_by_flights[0]) == flights_to(0.04, critical) // 2
    found, failed = flights_to(0.02, detectable), flights_to(0.02, critical)
    assert float(forecast.inspect_by_flights[1]) == found + (failed - found) // 2


def test_jacobian_adjoint_matches_central_differences(scenario):
    _, _, _, sub, obs, model, _, _ = scenario
    values, exact = log_crack_jacobian(model, sub, obs)  # 10 observations < 21 parameters
    many = Observations(
        torch.arange(10).repeat(3), torch.full((30,), NOW), obs.crack_length_m.repeat(3)
    )
    values_fd, differences = log_crack_jacobian(model, sub, many)  # 30 > 21: differences
    assert torch.allclose(values_fd[:10], values)
    assert torch.allclose(differences[:10], exact, rtol=1e-5, atol=1e-8)
    wanted = torch.zeros(differences.shape[1], dtype=torch.bool)
    wanted[-6:] = True  # the output layer of MLP#1
    _, some = log_crack_jacobian(model, sub, many, wanted)
    assert torch.equal(some[:, wanted], differences[:, wanted])
    assert not bool(some[:, ~wanted].any())


def test_censored_inspections_beat_ignoring_them():
    """Half the inspections find nothing (noisy measurement below the method's threshold).
    Fitting the detections alone over-predicts (they are the high draws); the censored
    likelihood removes that bias.  (80 inspections: with 20 the median's own sampling error,
    ~0.1 / sqrt(20), was as large as the bias tested.)"""
    law, flights, sd = ParisLaw(c=1.5e-10), 600, 0.1
    gen = torch.Generator().manual_seed(0)
    n = 160
    stress = 110.0 * torch.exp(0.05 * torch.randn(n, flights, generator=gen, dtype=torch.float64))
    lengths = torch.full((n,), flights)
    initial = torch.full((n,), law.initial_crack_m, dtype=torch.float64)
    truth = fast_march(DamageCell(PhysicsKernel(), law), stress, lengths, initial)[:, -1]
    loads = LoadHistory(stress, lengths)
    inspected = torch.arange(0, n, 2)
    count = len(inspected)
    measured = truth[inspected] * torch.exp(
        sd * torch.randn(count, generator=gen, dtype=torch.float64)
    )
    threshold = torch.full((count,), float(measured.median()))
    detected = measured > threshold
    censored = Observations(
        torch.arange(count), torch.full((count,), flights), measured, detected, threshold
    )
    found = censored.subset(detected)
    ignored = Observations(found.aircraft, found.flights, found.crack_length_m)
    sub, config = loads.select(inspected), TrainConfig(measurement_sd=sd)
    bias = {}
    for name, obs in (("ignored", ignored), ("censored", censored)):
        model, _ = fit_crack_model(sub, obs, law=law, config=config)
        with torch.no_grad():
            bias[name] = float(torch.log(model.final_crack(loads) / truth).median())
    assert bias["ignored"] > 0.03
    assert abs(bias["censored"]) < 0.5 * bias["ignored"]


def test_censored_loss_reduces_to_plain_loss_when_everything_is_detected():
    predicted = torch.tensor([0.011, 0.02], dtype=torch.float64)
    observed = torch.tensor([0.01, 0.021], dtype=torch.float64)
    obs = Observations(
        torch.arange(2),
        torch.ones(2, dtype=torch.long),
        observed,
        torch.ones(2, dtype=torch.bool),
        torch.full((2,), 0.002),
    )
    assert observation_loss(predicted, obs, "relative") == observation_loss(
        predicted, observed, "relative"
    )
    missed = Observations(
        obs.aircraft, obs.flights, observed, torch.tensor([True, False]), torch.full((2,), 0.005)
    )
    # a crack predicted far above the threshold is penalised more than one below it
    low = observation_loss(torch.tensor([0.01, 0.004], dtype=torch.float64), missed, "relative")
    high = observation_loss(torch.tensor([0.01, 0.008], dtype=torch.float64), missed, "relative")
    assert high > low > 0
    with pytest.raises(ValueError, match="relative"):
        observation_loss(predicted, missed, "mse")


def test_posterior_round_trip_through_model_file(scenario, tmp_path):
    _, _, _, _, _, model, posterior, _ = scenario
    path = tmp_path / "model.pt"
    artifacts.save(model, path, {"a": 1}, posterior=posterior.to_dict())
    data = path.read_bytes()
    restored_model, metrics = artifacts.from_bytes(data)
    stored = artifacts.posterior_from_bytes(data)
    assert stored is not None and metrics == {"a": 1}
    restored = LaplacePosterior.from_dict(stored)
    assert len(restored.others) == len(posterior.others) == 8
    assert torch.equal(restored.sample(5, seed=1), posterior.sample(5, seed=1))
    assert torch.equal(flat_parameters(restored_model), posterior.mean)
    assert artifacts.posterior_from_bytes(artifacts.to_bytes(model)) is None


def test_sampling_is_deterministic_for_a_seed(scenario):
    _, _, history, _, _, model, posterior, future = scenario
    assert torch.equal(posterior.sample(20, seed=7), posterior.sample(20, seed=7))
    assert not torch.equal(posterior.sample(20, seed=7), posterior.sample(20, seed=8))
    assert np.array_equal(future.draw(3), future.draw(3))
    assert not np.array_equal(future.draw(3), future.draw(4))
    plan = PlannedUtilization(3.0, np.array([100.0, 130.0]), np.array([0.75, 0.25]))
    planned = PlannedLoads(plan, aircraft=2, n_flights=4000, seed=1)
    assert np.array_equal(planned.draw(0), planned.draw(0))
    assert abs(float((planned.draw(0) == 130.0).mean()) - 0.25) < 0.02
    # the sampled covariance approaches the posterior's
    draws = posterior.sample(20000, seed=0)
    cov = torch.cov(draws.T)
    exact = posterior.covariance()
    assert float(torch.linalg.norm(cov - exact) / torch.linalg.norm(exact)) < 0.05
    one = dict(history=history.select(torch.arange(3)), samples=10, seed=5)
    small = ResampledLoads(future.recent_stress_mpa[:3], 50, seed=2)
    first = probabilistic_forecast(model, posterior, small, **one)
    second = probabilistic_forecast(model, posterior, small, **one)
    assert torch.equal(first.crack_p95_m, second.crack_p95_m)


def test_restarts_add_modes_sampled_in_turn(scenario):
    _, _, _, sub, obs, model, posterior, _ = scenario
    weights = flat_parameters(model)
    rng_state = torch.random.get_rng_state()
    single = laplace_posterior(model, sub, obs, restarts=1)
    pair = laplace_posterior(model, sub, obs, restarts=2)
    assert torch.equal(torch.random.get_rng_state(), rng_state)  # the global generator is kept
    assert torch.equal(flat_parameters(model), weights)  # the model is not refitted
    assert single.others == () and len(pair.others) == 1 and len(posterior.others) == 8
    assert torch.equal(posterior.mean, weights) and torch.equal(single.mean, weights)
    # restarts land on other weights: the modes differ where the data leave them free
    assert float((pair.others[0].mean - weights).abs().max()) > 1e-3
    # sample k comes from mode k mod 9; mode 0 draws as the single-mode posterior does
    draws = posterior.sample(20, seed=4)
    assert torch.equal(draws[0::9], single.sample(3, seed=4))
    hidden = ~torch.isfinite(posterior.others[1].prior_precision)  # fixed at each mode's fit
    assert torch.equal(draws[2::9][:, hidden], posterior.others[1].mean[hidden].expand(2, -1))
    assert torch.equal(single.sample(7, seed=4), single.sample(7, seed=4))


def test_restarts_rescue_an_unconverged_fit(scenario):
    """A fit stopped after one L-BFGS iteration: its single-mode bands miss most tails; the
    mixture with 4 converged restarts covers them and its median lies near the truth."""
    fleet, inspected, history, sub, obs, _, _, future = scenario
    model, _ = fit_crack_model(sub, obs, law=LAW, config=TrainConfig(lbfgs_iterations=1))
    truth = fleet.crack_length_m[:, NOW + AHEAD]
    uninspected = np.ones(fleet.size, dtype=bool)
    uninspected[inspected] = False
    coverage, worst = {}, {}
    for restarts in (1, 5):
        posterior = laplace_posterior(model, sub, obs, restarts=restarts)
        forecast = probabilistic_forecast(
            model, posterior, future, history=history, samples=50, seed=0
        )
        p05, p50, p95 = (
            q[:, -1].numpy()
            for q in (forecast.crack_p05_m, forecast.crack_p50_m, forecast.crack_p95_m)
        )
        coverage[restarts] = float(((truth >= p05) & (truth <= p95))[uninspected].mean())
        worst[restarts] = float(np.abs(p50 / truth - 1)[uninspected].max())
    assert coverage[1] < 0.5 and coverage[5] >= 0.85
    assert worst[5] < 0.05 < worst[1]


def test_bad_arguments_name_the_argument(scenario):
    _, _, history, sub, obs, model, posterior, future = scenario
    with pytest.raises(ValueError, match="count"):
        posterior.sample(0)
    with pytest.raises(ValueError, match="noise_floor"):
        laplace_posterior(model, sub, obs, noise_floor=0.0)
    with pytest.raises(ValueError, match="layers"):
        laplace_posterior(model, sub, obs, layers="middle")
    with pytest.raises(ValueError, match="restarts"):
        laplace_posterior(model, sub, obs, restarts=0)
    with pytest.raises(ValueError, match="crack_now_m / history"):
        probabilistic_forecast(model, posterior, future)
    with pytest.raises(ValueError, match="horizon_flights"):
        probabilistic_forecast(
            model, posterior, future, history=history, horizon_flights=torch.tensor([1])
        )
    with pytest.raises(ValueError, match="samples"):
        probabilistic_forecast(model, posterior, future, history=history, samples=0)
    with pytest.raises(ValueError, match="block_flights"):
        ResampledLoads([np.ones(3)], 10, block_flights=0)
    with pytest.raises(ValueError, match="flights_per_day"):
        PlannedUtilization(0.0, np.array([100.0]))
    with pytest.raises(ValueError, match="detection_a50_m"):
        Observations(torch.arange(1), torch.ones(1), torch.ones(1), torch.tensor([False]))
    with pytest.raises(ValueError, match="measurement_sd"):
        TrainConfig(measurement_sd=0.0)
    with pytest.raises(ValueError, match="meta"):
        LaplacePosterior.from_dict({"mean": torch.zeros(1)})


def test_history_forecast_starts_at_the_histories_own_initial_cracks():
    """A history restarted at 0.020 m (a repair) marches from there, not from a0."""
    law = ParisLaw()
    model = CrackGrowthModel(ModelSpec(kernel="physics", law=law))
    stress = torch.full((2, 100), 100.0, dtype=torch.float64)
    history = LoadHistory(stress, torch.tensor([100, 100]), torch.tensor([0.020, 0.005]))
    result = probabilistic_forecast(
        model, None, FixedLoads(np.full((2, 10), 100.0)), history=history, samples=2
    )
    expected = model.final_crack(history)
    assert float(result.crack_p50_m[0, 0]) == pytest.approx(float(expected[0]), rel=1e-6)
    assert float(result.crack_p50_m[0, 0]) > 0.02


def test_samples_sharing_their_weights_march_together_as_each_alone(monkeypatch):
    """Without a posterior the samples (each its own future draw, growth factor and weight by
    a later inspection) march as lanes of shared marches; the answer is the one-at-a-time one."""
    law = ParisLaw()
    model = CrackGrowthModel(ModelSpec(kernel="physics", law=law))
    gen = torch.Generator().manual_seed(4)
    stress = 90.0 + 40.0 * torch.rand(3, 400, generator=gen, dtype=torch.float64)
    history = LoadHistory(stress, torch.tensor([400, 250, 320]))
    flown = [s[:n].numpy() for s, n in zip(stress, history.lengths, strict=True)]
    future = ResampledLoads(flown, 300, seed=1)
    factors = torch.exp(0.3 * torch.randn(40, 3, generator=gen, dtype=torch.float64))
    later = Observations(torch.tensor([0, 2]), torch.tensor([400, 300]), torch.tensor([6e-3, 6e-3]))
    args = dict(history=history, samples=40, growth_factor=factors, observations=later)
    together = probabilistic_forecast(model, None, future, **args)
    monkeypatch.setattr("model.prognosis.LANES_PER_MARCH", 1)
    alone = probabilistic_forecast(model, None, future, **args)
    for name in ("crack_p05_m", "crack_p50_m", "crack_p95_m", "flights_to_critical_p05"):
        assert torch.equal(getattr(together, name), getattr(alone, name)), name
    assert torch.equal(together.effective_samples, alone.effective_samples)
    assert float(together.crack_p95_m[1, -1]) > float(
        together.crack_p05_m[1, -1]
    )  # tail 1: no later inspection


class _ScaledPhysicsKernel(DamageKernel):
    """A learned kernel the compiled march does not know: dK = s * F dS sqrt(pi a)."""

    name = "test-scaled-physics"

    def __init__(self, geometry_factor: float) -> None:
        super().__init__()
        self.geometry_factor = geometry_factor
        self.log_scale = torch.nn.Parameter(torch.zeros((), dtype=torch.float64))

    @classmethod
    def from_spec(cls, hidden, box, law):
        return cls(law.geometry_factor)

    def forward(self, stress_range_mpa, crack_length_m):
        physics = stress_intensity_range(stress_range_mpa, crack_length_m, self.geometry_factor)
        return physics * torch.exp(self.log_scale)


def test_a_kernel_without_compiled_march_trains_and_gets_a_posterior():
    """Registered kernels march sequentially, fit, and get a Laplace posterior and forecasts."""
    law = ParisLaw(c=6e-11)
    spec = ModelSpec(kernel="test-scaled-physics", law=law, box=InputBox((80, 140), (0.005, 0.05)))
    loads = LoadHistory(torch.full((3, 120), 110.0, dtype=torch.float64), torch.tensor([120] * 3))
    truth = CrackGrowthModel(ModelSpec(kernel="physics", law=replace(law, c=law.c * 1.3)))
    observed = truth.final_crack(loads).detach()
    observations = Observations(torch.arange(3), torch.tensor([120] * 3), observed)
    model = CrackGrowthModel(spec)
    fit(model, loads, observations, TrainConfig(lbfgs_iterations=50))
    assert math.exp(float(model.kernel.log_scale.detach())) ** law.m == pytest.approx(1.3, rel=1e-3)
    posterior = laplace_posterior(model, loads, observations, restarts=2)
    assert posterior.parameters == 1 and len(posterior.modes) == 2
    result = probabilistic_forecast(
        model, posterior, FixedLoads(np.full((3, 50), 110.0)), history=loads, samples=8
    )
    assert bool((result.crack_p95_m[:, -1] >= result.crack_p05_m[:, -1]).all())


def test_weighted_quantiles_of_equal_weights_are_order_statistics():
    """Equal weights (no observations) take the sorted values alone: the same bits as the
    sorted order with its weights gathered, the smallest value whose cumulative share reaches
    q."""
    gen = torch.Generator().manual_seed(3)
    values = torch.rand(200, 4, 6, generator=gen)
    for weights in (torch.full((200, 4), 1 / 200), torch.rand(200, 4, generator=gen)):
        order = values.argsort(dim=0)
        spread = weights[:, :, None].expand_as(values)
        cumulative = spread.gather(0, order).cumsum(dim=0)
        cumulative = cumulative / cumulative[-1:]
        expected = [
            values.gather(0, order).gather(0, (cumulative < q - 1e-12).sum(0, keepdim=True))[0]
            for q in (0.05, 0.5, 0.95)
        ]
        assert torch.equal(
            weighted_quantiles(values, weights, (0.05, 0.5, 0.95)), torch.stack(expected)
        )
