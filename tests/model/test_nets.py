import pytest
import torch

from model.cells import InputBox, MLPKernel, ResidualKernel
from model.hybrid import CrackGrowthModel, ModelSpec
from model.nets import MLP, THESIS_MLPS, THESIS_RNNS, SequenceBaseline

# Thesis Table 4.4 parameter counts.
THESIS_PARAMETERS = {1: 21, 2: 91, 3: 91, 4: 91, 5: 331, 6: 331, 7: 1211}


@pytest.mark.parametrize("number", sorted(THESIS_MLPS))
def test_thesis_mlps_have_table_4_4_parameter_counts(number):
    mlp = MLP(THESIS_MLPS[number])
    assert sum(p.numel() for p in mlp.parameters()) == THESIS_PARAMETERS[number]
    assert mlp(torch.rand(7, 2)).shape == (7,)


@pytest.mark.parametrize("hidden", [(), ((0, "tanh"),), ((5, "relu6"),)])
def test_mlp_rejects_bad_layers(hidden):
    with pytest.raises(ValueError):
        MLP(hidden)


def test_residual_kernel_starts_at_physics_and_mlp_kernel_does_not():
    box = InputBox((90.0, 135.0), (0.005, 0.05))
    stress, crack = torch.tensor([100.0, 130.0]), torch.tensor([0.01, 0.02])
    physics = stress * torch.sqrt(torch.pi * crack)
    assert torch.allclose(ResidualKernel(THESIS_MLPS[1], box)(stress, crack), physics)
    assert not torch.allclose(MLPKernel(THESIS_MLPS[1], box)(stress, crack), physics)


@pytest.mark.parametrize("kernel", ["residual", "mlp"])
def test_a_models_initial_weights_come_from_its_seed_not_the_global_generator(kernel):
    """Torch's global generator is the whole process's: another thread drawing from it (a
    model loaded meanwhile) must not move a retrain's initial weights (issue 20)."""
    spec = ModelSpec(
        kernel=kernel, hidden=THESIS_MLPS[3], box=InputBox((90.0, 135.0), (0.005, 0.05))
    )
    torch.manual_seed(1)
    first = CrackGrowthModel(spec, seed=5).state_dict()
    torch.manual_seed(2)
    torch.rand(9)
    again = CrackGrowthModel(spec, seed=5).state_dict()
    other = CrackGrowthModel(spec, seed=6).state_dict()
    assert all(torch.equal(first[k], again[k]) for k in first)
    assert not all(torch.equal(first[k], other[k]) for k in first)
    # what seeding the global generator, then building, gave (every version stored so far)
    torch.manual_seed(5)
    before = MLP(THESIS_MLPS[3])
    if kernel == "residual":
        before.zero_output()  # the residual kernel starts at the physics
    kept = {k.removeprefix("cell.kernel.mlp."): v for k, v in first.items() if ".mlp." in k}
    assert all(torch.equal(v.double(), kept[k]) for k, v in before.state_dict().items())


@pytest.mark.parametrize(("layers", "units"), THESIS_RNNS)
@pytest.mark.parametrize("kind", ["lstm", "gru"])
def test_thesis_rnn_baselines_are_constructible(kind, layers, units):
    net = SequenceBaseline(kind, layers, units, (90.0, 135.0), 0.005)
    out = net(torch.full((2, 9), 100.0))
    assert out.shape == (2, 9)
    assert bool((out > 0).all())


def test_rnn_baseline_rejects_unknown_kind():
    with pytest.raises(ValueError, match="kind"):
        SequenceBaseline("rnn", 1, 16, (90.0, 135.0), 0.005)
