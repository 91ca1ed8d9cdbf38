"""Growth laws, load channels and cycles per flight: Walker against Paris, the damage-equivalent
range against a cycle-by-cycle integration, every march on spectra."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from model.cells import InputBox
from model.growth_laws import GROWTH_LAWS, CycleSpectrum, GrowthConstants
from model.hybrid import CrackGrowthModel, ModelSpec
from model.integrate import LoadHistory
from model.physics import ParisLaw, stress_intensity_range

BOX = InputBox((40.0, 160.0), (0.005, 0.05))


def spectrum(aircraft: int, flights: int, cycles: int, seed: int) -> CycleSpectrum:
    """Random flights: one ground-air-ground cycle at R ~ -0.1 and gusts with R in [-0.3, 0.7],
    the last cycle of odd flights padded away, some half cycles."""
    gen = torch.Generator().manual_seed(seed)
    ranges = 20.0 + 60.0 * torch.rand(aircraft, flights, cycles, generator=gen, dtype=torch.float64)
    ranges[:, :, 0] = 100.0 + 20.0 * torch.rand(aircraft, flights, generator=gen).double()
    ratio = -0.3 + torch.rand(aircraft, flights, cycles, generator=gen, dtype=torch.float64)
    ratio[:, :, 0] = -0.1
    count = torch.randint(1, 4, (aircraft, flights, cycles), generator=gen).double()
    count[:, :, 0] = 1.0
    count[:, 1::2, -1] = 0.0
    ranges[:, 1::2, -1] = 0.0
    count[:, ::3, 1] = 0.5
    return CycleSpectrum(ranges, ratio, count)


def walker_spec(kernel: str = "physics", gamma: float = 0.6, c: float = 1e-11) -> ModelSpec:
    law = ParisLaw(c=c, m=3.5, gamma=gamma)
    return ModelSpec(kernel=kernel, law=law, box=BOX, growth_law="walker")


def test_walker_is_paris_at_gamma_one_and_at_zero_load_ratio() -> None:
    dk = torch.tensor([0.0, 5.0, 12.0, -1.0], dtype=torch.float64)
    ratio = torch.tensor([0.5, -0.3, 0.7, 0.1], dtype=torch.float64)
    paris, walker = GROWTH_LAWS["paris"], GROWTH_LAWS["walker"]
    one = GrowthConstants(1e-11, 3.5, 1.0)
    assert torch.equal(walker(dk, {"load_ratio": ratio}, one), paris(dk, {}, one))
    assert torch.equal(walker(dk, {}, GrowthConstants(1e-11, 3.5, 0.6)), paris(dk, {}, one))
    # the law as written: C [dK / (1 - R)**(1 - gamma)]**m
    expected = 1e-11 * (12.0 / (1 - 0.7) ** 0.4) ** 3.5
    got = walker(dk, {"load_ratio": ratio}, GrowthConstants(1e-11, 3.5, 0.6))
    assert float(got[2]) == pytest.approx(expected, rel=1e-12)
    assert float(got[3]) == 0.0  # a negative dK grows nothing


def test_equivalent_range_is_the_flights_damage_and_batch_invariant() -> None:
    cycles = spectrum(5, 40, 6, seed=1)
    constants = GrowthConstants(1e-11, 3.5, 0.6)
    walker = GROWTH_LAWS["walker"]
    eq = walker.equivalent_range(cycles, constants)
    damage = walker.flight_damage(
        cycles, torch.tensor(3.5, dtype=torch.float64), torch.tensor(0.6, dtype=torch.float64)
    )
    assert torch.allclose(eq**3.5, damage, rtol=1e-12)
    # the same flight gives the same bits in any batch (forecasts are batch-invariant)
    alone = walker.equivalent_range(cycles.pick(torch.tensor([3])), constants)
    assert torch.equal(alone[0], eq[3])
    # Paris reads no load ratio: its range is the plain [sum n dS**m]**(1/m)
    paris = GROWTH_LAWS["paris"].equivalent_range(cycles, constants)
    plain = (cycles.count * cycles.stress_range_mpa**3.5).sum(-1) ** (1 / 3.5)
    assert torch.allclose(paris, plain, rtol=1e-12)
    assert not torch.allclose(paris, eq, rtol=1e-3)


def test_single_range_histories_are_not_touched_by_any_law() -> None:
    loads = LoadHistory.from_sequences([[100.0, 120.0], [90.0]])
    assert loads.for_law("walker", GrowthConstants(1e-11, 3.5, 0.3)) is loads
    model = CrackGrowthModel(walker_spec("physics", gamma=0.3))
    paris = CrackGrowthModel(ModelSpec(kernel="physics", law=ParisLaw(c=1e-11, m=3.5)))
    assert torch.equal(model.trajectory(loads), paris.trajectory(loads))


def cycle_by_cycle(spec: ModelSpec, cycles: CycleSpectrum, a0: float) -> torch.Tensor:
    """The crack after every flight, integrated one cycle at a time (a updated after each
    cycle; a half cycle as half an increment), with the Walker law as written."""
    law = GROWTH_LAWS[spec.growth_law]
    aircraft, flights, k = cycles.stress_range_mpa.shape
    a = torch.full((aircraft,), a0, dtype=torch.float64)
    out = [a.clone()]
    for t in range(flights):
        for j in range(k):
            s = cycles.stress_range_mpa[:, t, j]
            dk = stress_intensity_range(s, a, spec.law.geometry_factor)
            rate = law(dk, {"load_ratio": cycles.load_ratio[:, t, j]}, spec.law.constants)
            a = a + cycles.count[:, t, j] * rate
        out.append(a.clone())
    return torch.stack(out, dim=1)


def test_per_flight_step_sums_the_cycles_increments() -> None:
    """The per-flight Euler step of dS_eq equals the sum of the cycles' increments with a held
    over the flight, and a cycle-by-cycle integration to within the crack's growth per flight."""
    cycles = spectrum(3, 400, 8, seed=2)
    spec = walker_spec("physics", gamma=0.6, c=2e-10)
    model = CrackGrowthModel(spec)
    lengths = torch.full((3,), 400, dtype=torch.long)
    loads = LoadHistory.from_cycles(cycles, lengths, "walker", spec.law.constants)
    a0 = 0.01
    traj = model.trajectory(loads, torch.full((3,), a0, dtype=torch.float64))
    # held a: one flight's increment is the sum of its cycles' increments exactly
    a = torch.full((3,), a0, dtype=torch.float64)
    held = a.clone()
    for j in range(cycles.stress_range_mpa.shape[2]):
        dk = stress_intensity_range(cycles.stress_range_mpa[:, 0, j], a)
        rate = GROWTH_LAWS["walker"](
            dk, {"load_ratio": cycles.load_ratio[:, 0, j]}, spec.law.constants
        )
        held = held + cycles.count[:, 0, j] * rate
    assert torch.allclose(traj[:, 1], held, rtol=1e-13, atol=0)
    reference = cycle_by_cycle(spec, cycles, a0)
    growth = reference[:, -1] / a0 - 1.0
    assert float(growth.min()) > 0.5  # the crack grew a lot, so the test can tell
    # the per-flight step's error is of the order of the crack's growth within a flight (here
    # 0.3 % a flight on average, ten times a fleet's; 3x overall, so the test can tell)
    per_flight = float((reference[:, 1:] / reference[:, :-1] - 1.0).mean())
    rel = (traj[:, -1] - reference[:, -1]).abs() / reference[:, -1]
    assert float(rel.max()) < 2.0 * per_flight
    # the load ratio matters: Paris on the same cycles is far off
    paris = CrackGrowthModel(ModelSpec(kernel="physics", law=ParisLaw(c=2e-10, m=3.5)))
    off = paris.trajectory(loads, torch.full((3,), a0, dtype=torch.float64))[:, -1]
    assert float(((off - reference[:, -1]).abs() / reference[:, -1]).min()) > 0.05


@pytest.mark.parametrize("kernel", ["physics", "residual", "mlp"])
def test_every_march_takes_spectra(kernel: str) -> None:
    """Compiled and sequential marches agree on a spectrum history (ragged, with cycles)."""
    torch.manual_seed(3)
    model = CrackGrowthModel(walker_spec(kernel, gamma=0.55), 3)
    if kernel != "physics":
        last = model.kernel.mlp.linears[-1]
        assert isinstance(last, torch.nn.Linear)
        with torch.no_grad():
            last.weight.normal_(0.0, 0.2)
            last.bias.fill_(0.5 if kernel == "mlp" else 0.1)
    cycles = spectrum(4, 200, 5, seed=4)
    lengths = torch.tensor([200, 150, 0, 17])
    loads = LoadHistory.from_cycles(cycles, lengths, "walker", model.spec.law.constants)
    fast = model.trajectory(loads, method="fast")
    slow = model.trajectory(loads, method="sequential")
    assert torch.allclose(fast, slow, rtol=1e-12, atol=0)
    assert torch.equal(
        fast[2], torch.full((201,), model.spec.law.initial_crack_m, dtype=torch.float64)
    )


def test_a_history_is_reduced_again_for_another_law() -> None:
    cycles = spectrum(2, 10, 4, seed=5)
    lengths = torch.tensor([10, 7])
    loads = LoadHistory.from_cycles(cycles, lengths, "paris", GrowthConstants(1e-11, 3.8))
    other = loads.for_law("walker", GrowthConstants(1e-11, 3.8, 0.5))
    assert other.reduced_for == ("walker", 3.8, 0.5)
    assert not torch.equal(other.stress_range_mpa, loads.stress_range_mpa)
    assert other.for_law("walker", GrowthConstants(2e-11, 3.8, 0.5)) is other  # C: same range
    picked = other.select(torch.tensor([1])).until(5)
    assert picked.cycles is not None and picked.cycles.stress_range_mpa.shape == (1, 5, 4)
    assert set(picked.channels) == {
        "stress_range_mpa",
        "cycle_range_mpa",
        "cycle_load_ratio",
        "cycle_count",
    }
    with pytest.raises(ValueError, match="which law"):
        LoadHistory(loads.stress_range_mpa, lengths, cycles=cycles)
    assert math.isfinite(float(other.stress_range_mpa.sum()))


def test_every_path_that_marches_a_history_reduces_it_under_the_models_law() -> None:
    """A history of cycles reduced under another law (Paris) gives, through the sampled
    forecasts, the fleet's samples and the posterior's Jacobian, exactly what the same flights
    reduced under the model's own law (Walker) give: no path marches a stale reduction."""
    from model.fleet_sampling import crack_samples
    from model.forecast import FixedLoads
    from model.integrate import Observations
    from model.prognosis import probabilistic_forecast
    from model.uncertainty_fit import log_crack_jacobian

    torch.manual_seed(5)
    model = CrackGrowthModel(walker_spec("residual", gamma=0.5, c=5e-11), 5)
    last = model.kernel.mlp.linears[-1]
    assert isinstance(last, torch.nn.Linear)
    with torch.no_grad():
        last.weight.normal_(0.0, 0.2)
    cycles = spectrum(3, 150, 4, seed=6)
    lengths = torch.tensor([150, 120, 90])
    stale = LoadHistory.from_cycles(cycles, lengths, "paris", GrowthConstants(1e-11, 3.0))
    fresh = model.loads_for(stale)
    own = LoadHistory(fresh.stress_range_mpa, lengths)  # one range per flight, the model's
    assert not torch.equal(stale.stress_range_mpa, own.stress_range_mpa)
    initial = torch.full((3,), 0.006, dtype=torch.float64)
    factors = torch.exp(0.2 * torch.randn(4, 3, dtype=torch.float64))
    a = crack_samples(model, None, stale, initial, samples=4, seed=1, growth_factor=factors)
    b = crack_samples(model, None, own, initial, samples=4, seed=1, growth_factor=factors)
    assert torch.equal(a, b)
    future = FixedLoads(np.full((3, 50), 110.0))
    runs = [
        probabilistic_forecast(
            model, None, future, history=h, samples=4, seed=2, growth_factor=factors
        ).crack_p50_m
        for h in (stale, own)
    ]
    assert torch.equal(runs[0], runs[1])
    obs = Observations(torch.tensor([0, 1]), torch.tensor([100, 60]), torch.tensor([0.007, 0.0068]))
    jac_stale = log_crack_jacobian(model, stale, obs)
    jac_own = log_crack_jacobian(model, own, obs)
    for x, y in zip(jac_stale, jac_own, strict=True):
        assert torch.equal(x, y)
