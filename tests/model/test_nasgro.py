"""The NASGRO law: its rate against hand-computed values, its ends (threshold and fracture), its
compiled march against the torch march, and the materials table's NASGRO columns.

TERMS are test inputs chosen to put the march's steps on both sides of the threshold, not an
alloy's constants (the materials table has none: model/data/materials.csv says why)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest
import torch
from pydantic import ValidationError

from app.config import Settings
from model import artifacts
from model.cells import InputBox
from model.growth_laws import GROWTH_LAWS, CycleSpectrum
from model.hybrid import CrackGrowthModel, ModelSpec
from model.integrate import LoadHistory
from model.materials import law_for, materials
from model.materials_file import read_table
from model.nasgro import NasgroTerms, nasgro_rate, opening_ratio, threshold
from model.nets import THESIS_MLPS
from model.paris_calibration import calibrate_law
from model.physics import ParisLaw
from model.runtime import configure_threads
from tests.model.corrections import give_correction

TERMS = NasgroTerms(
    threshold_mpa_sqrt_m=11.0,
    toughness_mpa_sqrt_m=60.0,
    p=0.5,
    q=1.0,
    alpha=2.0,
    smax_on_flow_stress=0.3,
    cth_plus=1.5,
    cth_minus=0.1,
)
C, N = 1.5e-11, 3.8


def hand_rate(dk: float, r: float, terms: NasgroTerms = TERMS) -> float:
    """The NASGRO equation written out in scalars (model.nasgro's docstring), long cracks."""
    alpha, s = terms.alpha, terms.smax_on_flow_stress
    a0 = (0.825 - 0.34 * alpha + 0.05 * alpha * alpha) * math.cos(math.pi * s / 2) ** (1 / alpha)
    a1 = (0.415 - 0.071 * alpha) * s
    a3 = 2 * a0 + a1 - 1
    a2 = 1 - a0 - a1 - a3
    if r >= 0:
        f = max(r, a0 + a1 * r + a2 * r * r + a3 * r * r * r)
    else:
        f = a0 + a1 * r if r >= -2 else a0 - 2 * a1
    cth = terms.cth_plus if r >= 0 else terms.cth_minus
    dk_th = terms.threshold_mpa_sqrt_m / ((1 - f) / ((1 - a0) * (1 - r))) ** (1 + cth * r)
    k_max = dk / (1 - r)
    if dk <= dk_th:
        return 0.0
    if k_max >= terms.toughness_mpa_sqrt_m:
        return math.inf
    return (
        C
        * ((1 - f) / (1 - r) * dk) ** N
        * (1 - dk_th / dk) ** terms.p
        / (1 - k_max / terms.toughness_mpa_sqrt_m) ** terms.q
    )


def rate(dk: float | list[float], r: float | list[float]) -> torch.Tensor:
    dks = torch.tensor(dk, dtype=torch.float64)
    return nasgro_rate(
        dks, torch.broadcast_to(torch.tensor(r, dtype=torch.float64), dks.shape), C, N, TERMS
    )


@pytest.mark.parametrize(
    ("dk", "r"), [(15.0, 0.0), (20.0, 0.1), (12.0, 0.5), (25.0, -1.0), (9.0, 0.7), (40.0, -2.5)]
)
def test_rate_equals_the_equation_written_out(dk: float, r: float) -> None:
    expected = hand_rate(dk, r)
    assert 0 < expected < math.inf  # every case lies between the threshold and fracture
    assert float(rate(dk, r)) == pytest.approx(expected, rel=1e-12)


def test_closure_and_threshold_at_their_defining_points() -> None:
    a0 = TERMS.closure_coefficients()[0]
    ratios = torch.tensor([-3.0, -1.0, 0.0, 1.0], dtype=torch.float64)
    f = opening_ratio(ratios, TERMS)
    a1 = TERMS.closure_coefficients()[1]
    # A0..A3 sum to 1: at R = 1 the crack is open over the whole (vanishing) range
    assert f.tolist() == pytest.approx([a0 - 2 * a1, a0 - a1, a0, 1.0], rel=1e-14)
    # at R = 0 the threshold is dK_0; a higher R lowers it (closure: less of the range is open)
    dk_th = threshold(torch.tensor([0.0, 0.5], dtype=torch.float64), TERMS)
    assert float(dk_th[0]) == pytest.approx(TERMS.threshold_mpa_sqrt_m, rel=1e-14)
    assert float(dk_th[1]) < TERMS.threshold_mpa_sqrt_m


def test_rate_vanishes_at_the_threshold() -> None:
    """da/dN = C' dK**n (1 - dK_th/dK)**p -> 0 as dK -> dK_th (R = 0, far from fracture: its
    term is near 1), and 0 at and below the threshold."""
    dk_th = TERMS.threshold_mpa_sqrt_m
    above = torch.tensor([dk_th * (1 + eps) for eps in (1e-2, 1e-4, 1e-6)], dtype=torch.float64)
    rates = rate([dk_th * 0.9, dk_th, *above.tolist()], 0.0)
    assert rates[:2].tolist() == [0.0, 0.0]
    assert rates[2] > rates[3] > rates[4] > 0 and float(rates[4]) < 0.02 * float(rates[2])
    fracture = (1 - above / TERMS.toughness_mpa_sqrt_m) ** TERMS.q
    rest = rates[2:] * fracture / (above**N * (1 - dk_th / above) ** TERMS.p)
    assert torch.allclose(rest, rest[0].expand(3), rtol=1e-10)  # C (1 - A0)**n, the same


def test_rate_grows_without_bound_at_fracture() -> None:
    """da/dN ~ 1 / (1 - K_max/K_c)**q as K_max -> K_c, the largest float at and past it (R =
    0.5: K_max = 2 dK)."""
    k_c = TERMS.toughness_mpa_sqrt_m
    below = torch.tensor([0.5 * k_c * (1 - eps) for eps in (1e-2, 1e-4, 1e-6)], dtype=torch.float64)
    rates = rate([*below.tolist(), 0.5 * k_c, 0.6 * k_c], 0.5)
    assert 0 < rates[0] < rates[1] < rates[2] < math.inf and float(rates[2]) > 1e3 * float(rates[0])
    runaway = torch.finfo(torch.float64).max
    assert rates[3:].tolist() == [runaway, runaway]
    dk_th = float(threshold(torch.tensor([0.5], dtype=torch.float64), TERMS))
    paris = below**N * (1 - dk_th / below) ** TERMS.p
    rest = rates[:3] * (1 - 2 * below / k_c) ** TERMS.q / paris
    assert torch.allclose(rest, rest[0].expand(3), rtol=1e-9)


def test_gradient_is_finite_wherever_the_rate_is() -> None:
    dk = torch.tensor([5.0, 11.0, 20.0, 30.0, 80.0], dtype=torch.float64, requires_grad=True)
    out = nasgro_rate(dk, torch.zeros_like(dk), C, N, TERMS)
    out[out < 1].sum().backward()
    assert dk.grad is not None and bool(dk.grad.isfinite().all())
    assert dk.grad[0] == 0 and dk.grad[2] > 0
    assert torch.autograd.gradcheck(
        lambda x: nasgro_rate(x, torch.full_like(x, 0.2), C, N, TERMS) * 1e9,
        torch.tensor([13.0, 22.0, 35.0], dtype=torch.float64, requires_grad=True),
    )


def test_one_cycle_flight_reduces_to_the_law_at_its_load_ratio() -> None:
    """A flight of one cycle (dS, R): one march step of its equivalent range (an R = 0 cycle)
    grows the crack as the law at (dK, R), in the Paris region exactly (no threshold, q = 0)."""
    paris_region = NasgroTerms(0.0, 1e6, 0.0, 0.0, 2.0, 0.3)
    constants = ParisLaw(c=C, m=N, nasgro=paris_region).constants
    law = GROWTH_LAWS["nasgro"]
    ratios = torch.tensor([-1.0, 0.0, 0.3, 0.7], dtype=torch.float64)
    ranges = torch.full_like(ratios, 100.0)
    cycles = CycleSpectrum(ranges[None, :, None], ratios[None, :, None], torch.ones(1, 4, 1))
    equivalent = law.equivalent_range(cycles, constants)[0]
    sqrt_pi_a = math.sqrt(math.pi * 0.01)
    stepped = law(equivalent * sqrt_pi_a, {}, constants)
    direct = law(ranges * sqrt_pi_a, {"load_ratio": ratios}, constants)
    assert torch.allclose(stepped, direct, rtol=1e-12, atol=0)
    table = torch.stack((ranges, ratios, torch.ones(4)), dim=1).numpy()
    by_run = law.flights_equivalent_range(table, torch.arange(5).numpy(), constants)
    assert by_run.tolist() == equivalent.tolist()


@pytest.fixture
def one_thread():
    before = torch.get_num_threads()
    configure_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.mark.usefixtures("one_thread")
@pytest.mark.parametrize("kernel", ["physics", "residual"])
def test_compiled_march_matches_the_torch_march(kernel: str) -> None:
    """Values and gradients (initial crack, weights, growth factor) of the compiled march against
    the sequential one, with steps below the threshold and a tail run past fracture (held)."""
    torch.manual_seed(3)
    box = InputBox((90.0, 130.0), (0.005, 0.05))
    law = ParisLaw(c=C, m=N, nasgro=TERMS)
    model = CrackGrowthModel(
        ModelSpec(kernel=kernel, hidden=THESIS_MLPS[1], law=law, box=box, growth_law="nasgro")
    )
    if kernel == "residual":
        give_correction(model)
    generator = torch.Generator().manual_seed(5)
    stress = 90.0 + 40.0 * torch.rand(3, 400, generator=generator, dtype=torch.float64)
    stress[2] *= 1.8  # this tail grows to K_c and is held
    lengths = torch.tensor([400, 250, 400])
    initial = torch.tensor([0.0035, 0.006, 0.02], dtype=torch.float64)
    loads = LoadHistory(stress * LoadHistory(stress, lengths).mask, lengths)
    factor = torch.tensor([0.8, 1.0, 1.2], dtype=torch.float64)
    outputs = []
    for method in ("fast", "sequential"):
        model.zero_grad()
        a0 = initial.clone().requires_grad_(True)
        f = factor.clone().requires_grad_(True)
        traj = model(loads.stress_range_mpa, loads.lengths, a0, f, method)
        (traj[:, 1:] * torch.linspace(1, 2, 400, dtype=torch.float64)).sum().backward()
        grads = [a0.grad, f.grad, *(p.grad for p in model.parameters())]
        outputs.append((traj.detach(), [g.clone() for g in grads if g is not None]))
    (fast, fast_grads), (seq, seq_grads) = outputs
    marched = model(loads.stress_range_mpa, loads.lengths, initial.clone().requires_grad_(True))
    assert "FastEulerMarch" in type(marched.grad_fn).__name__
    assert torch.allclose(fast, seq, rtol=1e-12, atol=0)
    for got, want in zip(fast_grads, seq_grads, strict=True):
        assert torch.allclose(got, want, rtol=1e-9, atol=1e-300)
    held = law.held_crack_m
    first_held = int((fast[2] == held).nonzero()[0])
    assert bool((fast[2, first_held:] == held).all())
    if kernel == "physics":  # grew, then fractured (the network's correction fractures it at once)
        assert first_held > 2 and float(fast[2, first_held - 1]) > float(fast[2, 0])
    assert float(fast[1, -1]) > float(fast[1, 0])
    # the first tail starts below the threshold: its first steps grow nothing
    dk0 = float(stress[0, 0]) * math.sqrt(math.pi * 0.0035)
    if kernel == "physics" and dk0 < TERMS.threshold_mpa_sqrt_m:
        assert float(fast[0, 1]) == float(fast[0, 0])


def test_materials_rows_load_by_name_and_nasgro_columns_parse(tmp_path: Path) -> None:
    table = materials()
    assert {"2024-T3", "7075-T6", "7075-T651"} <= set(table)
    assert all(row.nasgro is None for row in table.values())  # no cited NASGRO terms yet
    assert law_for("7075-T6").nasgro is None
    header = (Path(__file__).parents[2] / "model/data/materials.csv").read_text().splitlines()
    columns = next(line for line in header if line.startswith("name,"))
    path = tmp_path / "materials.csv"
    path.write_text(f"{columns}\nX,1e-11,3.0,1.0,30,dowling-2013,,3.0,60,0.5,1.0,2.0,0.3,1.5,0.1\n")
    row = read_table(path)["X"]
    assert row.nasgro == NasgroTerms(3.0, 60.0, 0.5, 1.0, 2.0, 0.3, 1.5, 0.1)
    path.write_text(f"{columns}\nX,1e-11,3.0,1.0,30,dowling-2013,,3.0,60,,,,,,\n")
    with pytest.raises(
        ValueError, match=r"material .X., column .nasgro_p.: empty, while other NASGRO columns"
    ):
        read_table(path)


def test_settings_need_nasgro_terms_and_refuse_to_learn_them() -> None:
    with pytest.raises(ValueError, match="the nasgro growth law needs its terms"):
        ModelSpec(kernel="physics", growth_law="nasgro")
    with pytest.raises(ValueError, match="alpha must be > 0"):
        replace(TERMS, alpha=0.0)
    with pytest.raises(ValidationError, match="growth_law nasgro needs a material"):
        Settings(growth_law="nasgro", material="2024-T3")
    with pytest.raises(ValueError, match="not calibrated from inspections"):
        calibrate_law(None, ParisLaw(nasgro=TERMS), None, growth_law="nasgro")  # type: ignore[arg-type]


def test_model_files_keep_the_nasgro_terms() -> None:
    law = ParisLaw(c=C, m=N, nasgro=TERMS)
    model = CrackGrowthModel(ModelSpec(kernel="physics", law=law, growth_law="nasgro"))
    loaded, _ = artifacts.from_bytes(artifacts.to_bytes(model))
    assert loaded.spec.law == law and loaded.spec.growth_law == "nasgro"
    assert "nasgro" not in artifacts.spec_to_dict(ModelSpec(kernel="physics"))["law"]


def test_a_reduction_is_redone_when_the_closure_changes() -> None:
    """The cached reduction's key holds the closure's terms: other terms, another dS_eq."""
    ranges = torch.full((1, 2, 1), 100.0, dtype=torch.float64)
    ratios = torch.tensor([[[0.5], [0.1]]], dtype=torch.float64)
    cycles = CycleSpectrum(ranges, ratios, torch.ones(1, 2, 1, dtype=torch.float64))
    plane_stress = ParisLaw(nasgro=TERMS).constants
    plane_strain = ParisLaw(nasgro=replace(TERMS, alpha=3.0)).constants
    history = LoadHistory.from_cycles(cycles, torch.tensor([2]), "nasgro", plane_stress)
    again = history.for_law("nasgro", plane_stress)
    other = history.for_law("nasgro", plane_strain)
    assert again is history and other.reduced_for == ("nasgro", N, 1.0, 3.0, 0.3)
    assert not torch.equal(other.stress_range_mpa, history.stress_range_mpa)
