"""A geometry factor tabulated over crack length: read at the current crack in every march."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import torch

from model.artifacts import from_bytes, to_bytes
from model.geometry import GeometryTable
from model.hybrid import CrackGrowthModel, ModelSpec
from model.integrate import LoadHistory
from model.nets import THESIS_MLPS
from model.physics import ParisLaw, stress_intensity_range
from model.runtime import configure_threads
from tests.model.corrections import give_correction
from tests.model.test_fast_march import BOX, make_loads, relative_error, values_and_gradients

# a factor rising towards an edge, and its points past both ends of the marched cracks
RISING = GeometryTable((0.004, 0.01, 0.02, 0.05), (1.0, 1.08, 1.3, 1.9))
LAW = ParisLaw(geometry_factor=RISING.value_at(0.005), geometry_table=RISING)
# knots among the cracks the agreement test marches (4-8 mm), so every segment and end is hit
DENSE = GeometryTable((0.0045, 0.005, 0.0055, 0.007), (1.0, 1.1, 1.25, 1.6))


@pytest.fixture(autouse=True, scope="module")
def _one_thread() -> Iterator[None]:
    before = torch.get_num_threads()
    configure_threads(1)
    yield
    torch.set_num_threads(before)


def test_table_interpolates_linearly_and_holds_outside() -> None:
    a = torch.tensor([0.001, 0.004, 0.007, 0.015, 0.05, 0.2], dtype=torch.float64)
    want = torch.tensor([1.0, 1.0, 1.04, 1.19, 1.9, 1.9], dtype=torch.float64)
    assert torch.allclose(RISING.at(a), want, rtol=0, atol=1e-14)
    dk = stress_intensity_range(torch.full_like(a, 100.0), a, RISING)
    assert torch.allclose(dk, want * 100.0 * torch.sqrt(torch.pi * a), rtol=1e-15)


@pytest.mark.parametrize(
    ("crack_length_m", "factor", "match"),
    [
        ((0.01,), (1.0,), "2 to"),
        ((0.01, 0.02), (1.0,), "same"),
        ((0.02, 0.01), (1.0, 1.1), "increasing"),
        ((0.01, 0.02), (1.0, 0.0), "factor"),
    ],
)
def test_table_rejects_bad_points(
    crack_length_m: tuple[float, ...], factor: tuple[float, ...], match: str
) -> None:
    with pytest.raises(ValueError, match=match):
        GeometryTable(crack_length_m, factor)


def _model(kernel: str, law: ParisLaw, seed: int = 3) -> CrackGrowthModel:
    torch.manual_seed(seed)
    spec = ModelSpec(kernel=kernel, hidden=THESIS_MLPS[3], box=BOX, law=law)
    model = CrackGrowthModel(spec, seed)
    if kernel == "residual":
        give_correction(model)
    return model


@pytest.mark.parametrize("kernel", ["physics", "residual"])
def test_compiled_march_matches_sequential_with_a_table(kernel: str) -> None:
    model = _model(kernel, ParisLaw(geometry_table=DENSE))
    # cracks from 4 to 8 mm grown over 300 flights of 180-260 MPa cross the table's knots
    loads, initial = make_loads(torch.float64)
    loads = LoadHistory(loads.stress_range_mpa * 2.0, loads.lengths)
    reference = values_and_gradients(model, loads, initial, "sequential")
    fast = values_and_gradients(model, loads, initial, "fast")
    for got, want in zip(fast, reference, strict=True):
        assert relative_error(got, want) <= 1e-10
    assert float(fast[0][0, -1]) > 0.007  # the march went past the last knot


def test_rising_table_grows_a_longer_crack_than_its_a0_value_held() -> None:
    flat = ParisLaw(geometry_factor=LAW.geometry_factor)
    # 8,000 flights of 120 MPa: ~22 mm with F held at its a0 value, well below a_crit (50 mm)
    loads = LoadHistory(torch.full((1, 8000), 120.0, dtype=torch.float64), torch.tensor([8000]))
    tabled = _model("physics", LAW).trajectory(loads)[0, -1]
    held = _model("physics", flat).trajectory(loads)[0, -1]
    assert float(held) < 0.03 and float(tabled) > 1.2 * float(held)
    # the constant path is the same march as a table that never changes
    still = GeometryTable((0.001, 0.1), (LAW.geometry_factor, LAW.geometry_factor))
    constant = ParisLaw(geometry_factor=LAW.geometry_factor, geometry_table=still)
    assert torch.allclose(_model("physics", constant).trajectory(loads)[0, -1], held, rtol=1e-13)


def test_model_file_keeps_the_table() -> None:
    model = _model("residual", LAW)
    loaded, _ = from_bytes(to_bytes(model))
    assert loaded.spec.law == LAW
    loads, initial = make_loads(torch.float64)
    with torch.no_grad():
        assert torch.equal(loaded.trajectory(loads, initial), model.trajectory(loads, initial))
    plain, _ = from_bytes(to_bytes(_model("residual", ParisLaw())))
    assert plain.spec.law.geometry_table is None
