import pytest
import torch
from torch.func import functional_call

from model.cells import DamageCell, InputBox, MLPKernel, PhysicsKernel, ResidualKernel
from model.integrate import LoadHistory, Observations, at_flights, march
from model.nets import THESIS_MLPS
from model.physics import ParisLaw

BOX = InputBox((90.0, 135.0), (0.005, 0.05))


def _perturbed(kernel):
    torch.manual_seed(3)
    kernel.double()
    with torch.no_grad():
        for p in kernel.parameters():
            p.add_(0.1 * torch.randn_like(p))
    return kernel


@pytest.mark.parametrize("kernel_type", [MLPKernel, ResidualKernel])
@pytest.mark.parametrize("number", [1, 2, 5])
def test_gradcheck_learnable_euler_cell(kernel_type, number):
    cell = DamageCell(_perturbed(kernel_type(THESIS_MLPS[number], BOX)), ParisLaw())
    stress = torch.tensor([95.0, 120.0, 131.0], dtype=torch.float64)
    crack = torch.tensor([0.006, 0.012, 0.03], dtype=torch.float64, requires_grad=True)
    names = [name for name, _ in cell.named_parameters()]

    def step(crack_m, *weights):
        return functional_call(cell, dict(zip(names, weights, strict=True)), (crack_m, stress))

    weights = tuple(p.detach().clone().requires_grad_(True) for p in cell.parameters())
    assert torch.autograd.gradcheck(step, (crack, *weights), eps=1e-7, atol=1e-9)


def test_march_holds_state_on_padded_flights():
    law = ParisLaw()
    cell = DamageCell(PhysicsKernel(), law)
    loads = LoadHistory.from_sequences([[100.0] * 5, [100.0] * 3])
    initial = torch.full((2,), law.initial_crack_m, dtype=torch.float64)
    traj = march(cell, loads.stress_range_mpa, initial, loads.mask)
    assert traj.shape == (2, 6)
    assert torch.equal(traj[1, 3:], traj[1, 3].expand(3))
    assert torch.allclose(traj[0, :4], traj[1, :4])
    assert bool((traj[0, 1:] > traj[0, :-1]).all())


def test_at_flights_picks_observed_steps():
    traj = torch.arange(12, dtype=torch.float64).reshape(2, 6)
    obs = Observations(torch.tensor([1, 0]), torch.tensor([0, 5]), torch.zeros(2))
    assert at_flights(traj, obs).tolist() == [6.0, 5.0]


def test_load_history_rejects_lengths_beyond_padding():
    with pytest.raises(ValueError, match="lengths"):
        LoadHistory(torch.zeros(2, 3), torch.tensor([3, 4]))


def test_input_box_rejects_empty_range():
    with pytest.raises(ValueError, match="stress_range_mpa"):
        InputBox((100.0, 100.0), (0.005, 0.05))


def test_loads_carry_their_initial_cracks_through_select_and_the_model():
    from model.hybrid import CrackGrowthModel, ModelSpec

    initial = torch.tensor([0.005, 0.008, 0.012], dtype=torch.float64)
    loads = LoadHistory(
        torch.full((3, 4), 100.0, dtype=torch.float64), torch.tensor([4, 2, 3]), initial
    )
    model = CrackGrowthModel(ModelSpec(kernel="physics"))
    with torch.no_grad():
        assert torch.equal(model.trajectory(loads)[:, 0], initial)
        picked = loads.select(torch.tensor([2, 1]))
        assert torch.equal(model.trajectory(picked)[:, 0], initial[[2, 1]])
    with pytest.raises(ValueError, match="initial_crack_m"):
        LoadHistory(loads.stress_range_mpa, loads.lengths, initial[:2])
