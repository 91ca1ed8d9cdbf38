"""The compiled march against the sequential reference: values and gradients agree."""

from __future__ import annotations

import math
from collections.abc import Iterator

import pytest
import torch
from torch import Tensor

from model import fast_march as fm
from model import fast_march_adjoint as adjoint
from model import fast_march_loops as loops
from model.cells import DamageKernel, InputBox
from model.fast_march import unsupported_reason
from model.fast_march_packing import pack_kernel
from model.geometry import GeometryTable
from model.hybrid import CrackGrowthModel, ModelSpec
from model.integrate import LoadHistory
from model.nets import THESIS_MLPS
from model.physics import ParisLaw, stress_intensity_range
from model.runtime import configure_threads
from model.uncertainty import flat_parameters
from tests.model.corrections import give_correction

BOX = InputBox((90.0, 130.0), (0.005, 0.05))
AIRCRAFT, FLIGHTS = 4, 300
LENGTHS = (300, 217, 0, 41)  # ragged: full, partial, never flown, short


@pytest.fixture(autouse=True, scope="module")
def _one_thread() -> Iterator[None]:
    """Small per-step ops: extra threads only wait on each other (see model/runtime.py)."""
    before = torch.get_num_threads()
    configure_threads(1)
    yield
    torch.set_num_threads(before)


CASES = [
    ("physics", THESIS_MLPS[1]),
    ("mlp", THESIS_MLPS[1]),
    ("mlp", THESIS_MLPS[2]),
    ("mlp", THESIS_MLPS[7]),
    ("mlp", ((4, "linear"), (3, "elu"))),
    ("residual", THESIS_MLPS[1]),
    ("residual", THESIS_MLPS[3]),
    ("residual", THESIS_MLPS[6]),
]


def make_model(
    kernel: str, hidden: tuple[tuple[int, str], ...], seed: int, law: ParisLaw | None = None
) -> CrackGrowthModel:
    torch.manual_seed(seed)
    spec = ModelSpec(kernel=kernel, hidden=hidden, box=BOX, law=law or ParisLaw())
    model = CrackGrowthModel(spec, seed)
    if kernel == "mlp":
        # Lift the output so most steps grow the crack; some stay negative (dK clamped at 0).
        last = model.kernel.mlp.linears[-1]
        assert isinstance(last, torch.nn.Linear)
        with torch.no_grad():
            last.bias += 0.3
    if kernel == "residual":
        give_correction(model)
    return model


def make_loads(dtype: torch.dtype, seed: int = 1) -> tuple[LoadHistory, Tensor]:
    generator = torch.Generator().manual_seed(seed)
    lengths = torch.tensor(LENGTHS)
    stress = 90.0 + 40.0 * torch.rand(AIRCRAFT, FLIGHTS, generator=generator, dtype=torch.float64)
    stress = stress * LoadHistory(stress, lengths).mask  # padded flights carry zero stress
    initial = 0.004 + 0.004 * torch.rand(AIRCRAFT, generator=generator, dtype=torch.float64)
    return LoadHistory(stress.to(dtype), lengths), initial.to(dtype)


def values_and_gradients(
    model: CrackGrowthModel, loads: LoadHistory, initial: Tensor, method: str
) -> list[Tensor]:
    """Trajectory, then d loss / d (initial crack, every parameter) for a loss on all steps."""
    initial = initial.clone().requires_grad_(True)
    traj = model.trajectory(loads, initial, method=method)
    generator = torch.Generator().manual_seed(7)
    weights = torch.randn(traj.shape, generator=generator, dtype=torch.float64).to(traj.dtype)
    loss = (weights * traj).sum() * 1e3 + (traj[:, -1] ** 2).sum() * 1e4
    inputs = [initial, *model.parameters()]
    grads = torch.autograd.grad(loss, inputs)
    return [traj.detach(), *grads]


def relative_error(actual: Tensor, expected: Tensor) -> float:
    scale = expected.abs().max().clamp_min(1e-30)
    return float(((actual - expected).abs().max() / scale).to(torch.float64))


@pytest.mark.parametrize(("dtype", "tolerance"), [(torch.float64, 1e-10), (torch.float32, 1e-5)])
@pytest.mark.parametrize(("kernel", "hidden"), CASES)
def test_fast_matches_sequential(
    kernel: str, hidden: tuple[tuple[int, str], ...], dtype: torch.dtype, tolerance: float
) -> None:
    model = make_model(kernel, hidden, seed=len(hidden)).to(dtype)
    loads, initial = make_loads(dtype)
    reference = values_and_gradients(model, loads, initial, "sequential")
    fast = values_and_gradients(model, loads, initial, "fast")
    assert fast[0].dtype == dtype and fast[0].shape == (AIRCRAFT, FLIGHTS + 1)
    for got, want in zip(fast, reference, strict=True):
        assert got.dtype == want.dtype and got.shape == want.shape
        assert relative_error(got, want) <= tolerance
    # cracks never shrink (dK is clamped at 0), physics-based kernels really grow them, and
    # padded flights keep them (a random thesis MLP may output dK <= 0: no growth is right then)
    traj = fast[0]
    assert bool((traj.diff(dim=1) >= 0).all())
    if kernel != "mlp":
        assert bool((traj[0, -1] > traj[0, 0]).item())
    assert torch.equal(traj[2], traj[2, :1].expand(FLIGHTS + 1))
    assert torch.equal(traj[3, LENGTHS[3] :], traj[3, LENGTHS[3]].expand(FLIGHTS + 1 - LENGTHS[3]))


def test_negative_network_output_grows_nothing() -> None:
    model = make_model("mlp", THESIS_MLPS[1], seed=0)
    last = model.kernel.mlp.linears[-1]
    assert isinstance(last, torch.nn.Linear)
    with torch.no_grad():
        last.weight.zero_()
        last.bias.fill_(-0.5)
    loads, initial = make_loads(torch.float64)
    fast = values_and_gradients(model, loads, initial, "fast")
    assert torch.equal(fast[0], initial.unsqueeze(1).expand_as(fast[0]))
    assert all(float(g.abs().max()) == 0.0 for g in fast[2:])


def test_physics_kernel_matches_hand_written_euler() -> None:
    model = CrackGrowthModel(ModelSpec(kernel="physics"))
    law = model.spec.law
    loads = LoadHistory(torch.full((1, 50), 120.0, dtype=torch.float64), torch.tensor([50]))
    traj = model.trajectory(loads, method="fast")
    a = torch.tensor([law.initial_crack_m], dtype=torch.float64)
    for k in range(50):
        a = a + law.c * stress_intensity_range(torch.tensor(120.0), a) ** law.m
        assert float(traj[0, k + 1]) == pytest.approx(float(a[0]), rel=1e-14)


def test_gradcheck_against_finite_differences() -> None:
    model = make_model("residual", THESIS_MLPS[3], seed=3)
    loads, initial = make_loads(torch.float64)
    loads = LoadHistory(loads.stress_range_mpa[:, :20], loads.lengths.clamp_max(20))
    flat = flat_parameters(model).requires_grad_(True)
    factor = torch.linspace(0.7, 1.4, len(initial), dtype=torch.float64).requires_grad_(True)

    def trajectory_mm(a0: Tensor, theta: Tensor, growth_factor: Tensor) -> Tensor:
        stress, lengths = loads.stress_range_mpa, loads.lengths
        return 1e3 * model.trajectory_with(theta, stress, lengths, a0, growth_factor)

    a0 = initial.clone().requires_grad_(True)
    assert torch.autograd.gradcheck(trajectory_mm, (a0, flat, factor), eps=1e-7, atol=1e-7)


def test_diverging_network_is_held_like_the_reference() -> None:
    """A lane whose march turns nan (here: a nan weight) reads as run past fracture, in both
    marches: held at the law's held crack, where the other lanes are untouched."""
    model = make_model("mlp", THESIS_MLPS[1], seed=0)
    first = model.kernel.mlp.linears[0]
    assert isinstance(first, torch.nn.Linear)
    with torch.no_grad():
        first.bias[0] = math.nan
    loads, initial = make_loads(torch.float64)
    with torch.no_grad():
        fast = model.trajectory(loads, initial, method="fast")
        reference = model.trajectory(loads, initial, method="sequential")
    held = model.spec.law.held_crack_m
    assert torch.equal(fast == held, reference == held)
    assert float(fast[0, -1]) == held and not bool((fast[2] == held).any())


def test_fast_march_rejects_mismatched_shapes() -> None:
    model = make_model("mlp", THESIS_MLPS[1], seed=0)
    loads, initial = make_loads(torch.float64)
    with pytest.raises(ValueError, match="initial_crack_m"):
        fm.fast_march(model.cell, loads.stress_range_mpa, loads.lengths, initial[:2])
    with pytest.raises(ValueError, match="lengths"):
        fm.fast_march(model.cell, loads.stress_range_mpa, loads.lengths[:2], initial)
    with pytest.raises(ValueError, match="growth_factor"):
        fm.fast_march(model.cell, loads.stress_range_mpa, loads.lengths, initial, initial[:2])


def test_unknown_method_rejected() -> None:
    model = CrackGrowthModel(ModelSpec(kernel="physics"))
    loads, _ = make_loads(torch.float64)
    with pytest.raises(ValueError, match="method"):
        model.trajectory(loads, method="rk4")


class _ShiftedKernel(DamageKernel):
    """A kernel the compiled march does not know: must fall back to the sequential march."""

    def __init__(self) -> None:
        super().__init__()
        self.shift = torch.nn.Parameter(torch.tensor(1.0, dtype=torch.float64))

    def forward(self, stress_range_mpa: Tensor, crack_length_m: Tensor) -> Tensor:
        return stress_intensity_range(stress_range_mpa, crack_length_m) * self.shift


def test_auto_falls_back_for_other_kernels_and_fast_refuses() -> None:
    model = CrackGrowthModel(ModelSpec(kernel="physics"))
    model.cell.kernel = _ShiftedKernel()
    loads, initial = make_loads(torch.float64)
    assert unsupported_reason(model.cell, loads.stress_range_mpa) is not None
    traj = model.trajectory(loads, initial)
    traj[:, -1].sum().backward()
    shift = model.kernel.shift
    assert shift.grad is not None and float(shift.grad) > 0
    with pytest.raises(ValueError, match="fast march unavailable"):
        model.trajectory(loads, initial, method="fast")


def test_auto_uses_fast_path_for_thesis_kernels() -> None:
    model = make_model("mlp", THESIS_MLPS[1], seed=0)
    loads, initial = make_loads(torch.float64)
    traj = model.trajectory(loads, initial.requires_grad_(True))
    assert traj.grad_fn is not None and "FastEulerMarch" in type(traj.grad_fn).__name__


def test_one_compiled_signature_serves_every_kernel_and_dtype() -> None:
    """Each new signature is another ~10 s cold compile; float32, ragged and all kinds share one."""
    fm.warm_up()
    for kernel, hidden in CASES[:2]:
        for dtype in (torch.float32, torch.float64):
            model = make_model(kernel, hidden, seed=0).to(dtype)
            loads, initial = make_loads(dtype)
            model.trajectory(loads, initial.requires_grad_(True), method="fast").sum().backward()
    assert len(loops.march_forward.signatures) == 1
    assert len(adjoint.march_backward.signatures) == 1


def test_auto_keeps_the_gradient_to_stress_ranges() -> None:
    """The compiled march gives no d/d(stress); auto must then take the sequential march."""
    model = make_model("residual", THESIS_MLPS[1], seed=0)
    loads, initial = make_loads(torch.float64)
    stress = loads.stress_range_mpa.clone().requires_grad_(True)
    traj = model.trajectory(LoadHistory(stress, loads.lengths), initial)
    traj[:, -1].sum().backward()
    assert stress.grad is not None and float(stress.grad[0].abs().sum()) > 0
    with pytest.raises(ValueError, match="stress ranges"):
        model.trajectory(LoadHistory(stress, loads.lengths), initial, method="fast")


@pytest.mark.parametrize("kernel, hidden", CASES[:3])
def test_growth_factors_march_like_the_reference(kernel: str, hidden: tuple) -> None:
    """Per-aircraft growth factors: compiled and sequential agree in values and gradients."""
    model = make_model(kernel, hidden, seed=1)
    loads, initial = make_loads(torch.float64)
    factor = torch.linspace(0.6, 1.5, len(initial), dtype=torch.float64)
    outputs = {}
    for method in ("fast", "sequential"):
        model.zero_grad()
        f = factor.clone().requires_grad_(True)
        traj = model(loads.stress_range_mpa, loads.lengths, initial, f, method)
        traj[:, -1].sum().backward()
        assert f.grad is not None
        outputs[method] = (traj.detach(), f.grad.clone())
    (fast, fast_grad), (seq, seq_grad) = outputs["fast"], outputs["sequential"]
    assert torch.allclose(fast, seq, rtol=1e-12, atol=0)
    assert torch.allclose(fast_grad, seq_grad, rtol=1e-9, atol=0)
    plain = model.trajectory(loads, initial).detach()
    flown = loads.lengths > 0
    assert torch.equal(fast[:, -1] > plain[:, -1], (factor > 1) & flown)


def test_other_steps_and_laws_take_the_sequential_march() -> None:
    """The fast path is chosen by the whole cell: a midpoint step has no compiled march."""
    model = CrackGrowthModel(ModelSpec(kernel="physics", step="midpoint"))
    loads, initial = make_loads(torch.float64)
    assert "Euler" in str(unsupported_reason(model.cell, loads.stress_range_mpa))
    traj = model.trajectory(loads, initial)
    euler = CrackGrowthModel(ModelSpec(kernel="physics")).trajectory(loads, initial)
    assert traj.grad_fn is None or "FastEulerMarch" not in type(traj.grad_fn).__name__
    assert 0 < float((traj[:, -1] / euler[:, -1] - 1).abs().max()) < 1e-3


@pytest.mark.parametrize(("kernel", "hidden"), [CASES[0], CASES[1], CASES[5], CASES[7]])
@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_reading_points_gives_the_trajectory_bits(
    kernel: str, hidden: tuple[tuple[int, str], ...], dtype: torch.dtype
) -> None:
    """`at` reads the trajectory's own values, bit for bit, in any order, past a lane's last
    flight too, with growth factors; with a gradient it indexes the trajectory."""
    model = make_model(kernel, hidden, seed=2).to(dtype)
    loads, initial = make_loads(dtype)
    factor = torch.tensor([0.7, 1.0, 1.3, 2.0], dtype=dtype)
    args = (loads.stress_range_mpa, loads.lengths, initial, factor)
    rows = torch.tensor([3, 0, 1, 2, 0, 3, 1])
    flights = torch.tensor([41, 300, 0, 5, 0, 300, 217])
    with torch.no_grad():
        expected = model(*args)[rows, flights]
        assert torch.equal(model(*args, at=(rows, flights)), expected)
    graded = model(
        loads.stress_range_mpa,
        loads.lengths,
        initial.requires_grad_(True),
        factor,
        at=(rows, flights),
    )
    assert graded.requires_grad and torch.equal(graded.detach(), expected)
    with pytest.raises(ValueError, match="points must lie"):
        fm.fast_march_at(model.cell, *args, torch.tensor([0]), torch.tensor([FLIGHTS + 1]))


@pytest.mark.parametrize(("kernel", "hidden"), [CASES[0], CASES[1], CASES[5], CASES[7]])
@pytest.mark.parametrize("table", [False, True])
def test_points_with_a_gradient_give_the_trajectory_gradient_bits(
    kernel: str, hidden: tuple[tuple[int, str], ...], table: bool
) -> None:
    """With a gradient, `at` marches fast_march_points: its values and its gradients (weights,
    initial crack, growth factor) are those of indexing the whole trajectory, bit for bit, with
    a point read twice, flight 0, a lane's last flight and points past it, and a geometry
    table."""
    rising = GeometryTable((0.004, 0.006, 0.009, 0.02), (1.0, 1.05, 1.2, 1.6))
    law = ParisLaw(geometry_factor=rising.value_at(0.004), geometry_table=rising)
    model = make_model(kernel, hidden, seed=3, law=law if table else None)
    assert (pack_kernel(model.kernel)[0].geometry_knots.size > 0) == (table and kernel != "mlp")
    loads, start = make_loads(torch.float64)
    rows = torch.tensor([3, 0, 1, 2, 0, 3, 1, 1, 0])
    flights = torch.tensor([41, 250, 0, 5, 0, 120, 217, 217, 250])
    weights = torch.linspace(-1.0, 2.0, len(rows), dtype=torch.float64)

    def gradients(points: bool) -> list[Tensor]:
        initial = start.clone().requires_grad_(True)
        factor = torch.tensor([0.7, 1.0, 1.3, 2.0], dtype=torch.float64, requires_grad=True)
        args = (loads.stress_range_mpa, loads.lengths, initial, factor)
        if points:
            read = model(*args, at=(rows, flights))
            assert "FastEulerPoints" in type(read.grad_fn).__name__
        else:
            read = model(*args)[rows, flights]
        loss = (weights * torch.log(read)).sum()
        return [read.detach(), *torch.autograd.grad(loss, [initial, factor, *model.parameters()])]

    for got, expected in zip(gradients(True), gradients(False), strict=True):
        assert torch.equal(got, expected)


def test_a_zero_output_layer_reads_like_the_physics() -> None:
    """A residual kernel at its start (output layer zero) reads the physics loops' values, the
    same bits as its own march."""
    model = CrackGrowthModel(ModelSpec(kernel="residual", hidden=THESIS_MLPS[1], box=BOX))
    loads, initial = make_loads(torch.float64)
    rows, flights = torch.arange(AIRCRAFT), loads.lengths
    with torch.no_grad():
        traj = model(loads.stress_range_mpa, loads.lengths, initial)
        read = model(loads.stress_range_mpa, loads.lengths, initial, at=(rows, flights))
    assert torch.equal(read, traj[rows, flights])
    physics = CrackGrowthModel(ModelSpec(kernel="physics", box=BOX))
    with torch.no_grad():
        assert torch.equal(
            read, physics(loads.stress_range_mpa, loads.lengths, initial)[rows, flights]
        )


def test_a_history_read_again_is_read_flights_major_to_the_same_bits() -> None:
    """The second read of one stress tensor marches it flights-major (model.fast_march_stress),
    to the trajectory's bits; a change in place, or another tensor, is read afresh."""
    model = make_model(*CASES[5], seed=3)
    loads, initial = make_loads(torch.float64)
    stress = loads.stress_range_mpa.clone()
    rows = torch.tensor([0, 1, 2, 3, 0])
    flights = torch.tensor([300, 217, 0, 41, 150])
    with torch.no_grad():
        for _ in range(3):
            expected = model(stress, loads.lengths, initial)[rows, flights]
            got = fm.fast_march_at(model.cell, stress, loads.lengths, initial, None, rows, flights)
            assert torch.equal(got, expected)
        kept = fm.READ_AGAIN._last
        assert kept is not None and kept[2] is not None and kept[2].flags.f_contiguous
        stress[:, 100:] *= 1.1
        expected = model(stress, loads.lengths, initial)[rows, flights]
        got = fm.fast_march_at(model.cell, stress, loads.lengths, initial, None, rows, flights)
        assert torch.equal(got, expected)
        assert fm.fast_march_at(
            model.cell, stress, loads.lengths, initial, None, rows, flights
        ).equal(expected)
