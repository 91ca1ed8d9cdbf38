import pytest
import torch

from model.cells import DamageCell, PhysicsKernel
from model.integrate import LoadHistory, Observations, march
from model.physics import ParisLaw
from model.train import TrainConfig, fit, fit_crack_model, fit_sequence_baseline

# A short, fast-growing fleet keeps the sequential march cheap in tests.
LAW = ParisLaw(c=1.5e-10)
FLIGHTS = 600


def _fleet(aircraft: int, geometry_slope: float, seed: int = 0):
    """Stress histories and the true crack after each flight, optionally with F(a) = 1 + slope*(a-a0)/a0."""
    gen = torch.Generator().manual_seed(seed)
    level = 90.0 + 35.0 * torch.rand(aircraft, 1, generator=gen, dtype=torch.float64)
    stress = level * torch.exp(
        0.03 * torch.randn(aircraft, FLIGHTS, generator=gen, dtype=torch.float64)
    )

    class TrueKernel(PhysicsKernel):
        def forward(self, s, a):
            factor = 1.0 + geometry_slope * (a - LAW.initial_crack_m) / LAW.initial_crack_m
            return factor * super().forward(s, a)

    initial = torch.full((aircraft,), LAW.initial_crack_m, dtype=torch.float64)
    truth = march(DamageCell(TrueKernel(), LAW), stress, initial)
    return LoadHistory(stress, torch.full((aircraft,), FLIGHTS)), truth


def _inspect_final(truth: torch.Tensor, aircraft: torch.Tensor) -> Observations:
    return Observations(aircraft, torch.full_like(aircraft, FLIGHTS), truth[aircraft, -1])


def _errors(model, loads, truth):
    with torch.no_grad():
        return (model.final_crack(loads) / truth[:, -1] - 1).abs()


def test_residual_hybrid_keeps_exact_physics_when_truth_is_paris():
    loads, truth = _fleet(20, geometry_slope=0.0)
    model, _ = fit_crack_model(loads, _inspect_final(truth, torch.arange(0, 20, 4)), law=LAW)
    assert float(_errors(model, loads, truth).max()) < 1e-6


def test_residual_hybrid_learns_a_missing_geometry_factor():
    loads, truth = _fleet(24, geometry_slope=0.08)
    order = torch.argsort(truth[:, -1])
    inspected = order[torch.linspace(0, 23, 6).round().long()]
    physics, _ = fit_crack_model(loads, _inspect_final(truth, inspected), kernel="physics", law=LAW)
    hybrid, result = fit_crack_model(loads, _inspect_final(truth, inspected), law=LAW)
    physics_error = _errors(physics, loads, truth)
    hybrid_error = _errors(hybrid, loads, truth)
    assert float(physics_error.max()) > 0.05  # the discrepancy is real
    assert float(hybrid_error.max()) < 0.2 * float(physics_error.max())
    assert result.loss_history[-1] < result.loss_history[0]


def test_first_order_training_reduces_loss_and_keeps_best_weights():
    loads, truth = _fleet(8, geometry_slope=0.08)
    config = TrainConfig(optimizer="adam", epochs=15, learning_rate=1e-2)
    _model, result = fit_crack_model(
        loads, _inspect_final(truth, torch.arange(8)), law=LAW, config=config
    )
    assert min(result.loss_history) < result.loss_history[0]
    assert result.final_loss == pytest.approx(min(result.loss_history), rel=1e-9)


def test_training_is_reproducible_for_a_seed():
    loads, truth = _fleet(6, geometry_slope=0.08)
    obs = _inspect_final(truth, torch.arange(6))
    config = TrainConfig(seed=7, lbfgs_iterations=5)
    first, _ = fit_crack_model(loads, obs, kernel="mlp", law=LAW, config=config)
    second, _ = fit_crack_model(loads, obs, kernel="mlp", law=LAW, config=config)
    for a, b in zip(first.parameters(), second.parameters(), strict=True):
        assert torch.equal(a, b)


def test_progress_reaches_one():
    loads, truth = _fleet(4, geometry_slope=0.0)
    seen: list[float] = []
    fit_crack_model(
        loads,
        _inspect_final(truth, torch.arange(4)),
        law=LAW,
        config=TrainConfig(lbfgs_iterations=3),
        progress=seen.append,
    )
    assert seen[-1] == 1.0
    assert all(0.0 <= p <= 1.0 for p in seen)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [({"optimizer": "sgd"}, "optimizer"), ({"loss": "l1"}, "loss"), ({"epochs": 0}, "epochs")],
)
def test_train_config_rejects_bad_options(kwargs, field):
    with pytest.raises(ValueError, match=field):
        TrainConfig(**kwargs)


def test_fit_rejects_no_observations_and_observations_after_last_flight():
    loads, truth = _fleet(2, geometry_slope=0.0)
    model, _ = fit_crack_model(
        loads,
        _inspect_final(truth, torch.arange(2)),
        law=LAW,
        config=TrainConfig(lbfgs_iterations=1),
    )
    empty = Observations(
        torch.zeros(0, dtype=torch.long), torch.zeros(0, dtype=torch.long), torch.zeros(0)
    )
    with pytest.raises(ValueError, match="observations"):
        fit(model, loads, empty)
    late = Observations(torch.tensor([0]), torch.tensor([FLIGHTS + 1]), torch.tensor([0.01]))
    with pytest.raises(ValueError, match="after"):
        fit(model, loads, late)


def test_sequence_baseline_trains_on_observed_flights_only():
    loads, truth = _fleet(4, geometry_slope=0.0)
    obs = Observations(torch.tensor([0, 1, 2]), torch.tensor([200, 400, 600]), truth[:3, -1])
    config = TrainConfig(optimizer="adam", epochs=8, learning_rate=1e-2)
    net, result = fit_sequence_baseline(
        loads, obs, kind="gru", layers=1, units=8, law=LAW, config=config
    )
    assert result.final_loss == pytest.approx(min(result.loss_history), rel=1e-9)
    assert result.final_loss < result.loss_history[0]
    # flights after each tail's last observation (reversed: the fleet's stress range is kept)
    # and the unobserved tail's flights leave the fitted weights exactly as they were
    stress = loads.stress_range_mpa.clone()
    stress[0, 200:] = stress[0, 200:].flip(0)
    stress[1, 400:] = stress[1, 400:].flip(0)
    stress[3] = stress[3].flip(0)
    changed = LoadHistory(stress, loads.lengths)
    other, _ = fit_sequence_baseline(
        changed, obs, kind="gru", layers=1, units=8, law=LAW, config=config
    )
    assert not torch.equal(stress, loads.stress_range_mpa)
    for (name, mine), theirs in zip(
        net.state_dict().items(), other.state_dict().values(), strict=True
    ):
        assert torch.equal(mine, theirs), name
    with pytest.raises(ValueError, match="optimizer"):
        fit_sequence_baseline(
            loads, obs, kind="gru", layers=1, units=8, law=LAW, config=TrainConfig()
        )


def test_fit_honours_the_process_thread_setting(monkeypatch: pytest.MonkeyPatch) -> None:
    """FLEETPINN_THREADS reaches training: a default TrainConfig does not override it."""
    from model.runtime import THREADS_ENV

    loads = LoadHistory.from_sequences([[120.0] * 50, [100.0] * 50])
    observations = Observations(
        torch.tensor([0, 1]), torch.tensor([50, 50]), torch.tensor([0.0051, 0.00505])
    )
    monkeypatch.setenv(THREADS_ENV, "2")
    try:
        fit_crack_model(loads, observations, config=TrainConfig(lbfgs_iterations=2))
        assert torch.get_num_threads() == 2
        fit_crack_model(loads, observations, config=TrainConfig(lbfgs_iterations=2, threads=1))
        assert torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(1)
