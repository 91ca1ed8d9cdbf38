"""Fleet sampling: crack-now samples, stacked futures, band chunks and per-tail risk."""

import numpy as np
import pytest
import torch

from model import forecast as fc
from model.fleet import FleetConfig, generate_fleet
from model.fleet_sampling import (
    StackedLoads,
    band_chunks,
    crack_samples,
    daily_flights,
    sample_risk,
)
from model.hybrid import CrackGrowthModel, ModelSpec
from model.integrate import LoadHistory

PHYSICS = CrackGrowthModel(ModelSpec(kernel="physics"))


def test_daily_flights_count_whole_flights_by_each_day() -> None:
    assert daily_flights(3, 2.5).tolist() == [0, 2, 5, 7]
    assert daily_flights(0, 4.0).tolist() == [0]


def test_band_chunks_bound_tails_times_points_and_keep_every_tail() -> None:
    rates = [4.0, 1.0, 4.0, 2.5, 1.0]
    assert band_chunks(rates, 30, bands=False) == [[0, 1, 2, 3, 4]]
    chunks = band_chunks(rates, 30, bands=True, max_values=70)
    assert sorted(i for c in chunks for i in c) == list(range(5))
    for chunk in chunks:
        points = set().union(*(set(daily_flights(30, rates[i]).tolist()) for i in chunk))
        assert len(chunk) == 1 or len(points) * len(chunk) <= 70
    assert [1, 4] in chunks  # equal rates share their points


def test_stacked_loads_pad_each_tail_and_keep_its_own_draws() -> None:
    a = fc.ResampledLoads([np.array([100.0, 120.0])], 5, seed=1, block_flights=1)
    b = fc.ResampledLoads([np.array([90.0]), np.array([80.0, 70.0])], 3, seed=2)
    stacked = StackedLoads([a, b])
    assert (stacked.aircraft, stacked.n_flights) == (3, 5)
    draw = stacked.draw(7)
    np.testing.assert_array_equal(draw[0], a.draw(7)[0])
    np.testing.assert_array_equal(draw[1:, :3], b.draw(7))
    assert (draw[1:, 3:] == 0).all()
    with pytest.raises(ValueError, match="parts"):
        StackedLoads([])


def test_crack_samples_without_a_posterior_repeat_the_fitted_crack() -> None:
    loads = LoadHistory(torch.full((2, 30), 150.0, dtype=torch.float64), torch.tensor([30, 12]))
    initial = torch.tensor([0.005, 0.01], dtype=torch.float64)
    samples = crack_samples(PHYSICS, None, loads, initial, samples=4, seed=0)
    with torch.no_grad():
        trajectory = PHYSICS.trajectory(loads, initial)
    assert samples.shape == (4, 2)
    expected = trajectory[torch.arange(2), loads.lengths]
    assert torch.equal(samples, expected.expand(4, -1))
    with pytest.raises(ValueError, match="samples"):
        crack_samples(PHYSICS, None, loads, initial, samples=0, seed=0)


def test_a_tails_risk_does_not_depend_on_its_companions() -> None:
    recent = [np.array([150.0, 200.0, 120.0, 90.0]), np.array([300.0, 310.0])]
    futures = [fc.ResampledLoads([r], 400, seed=i, block_flights=2) for i, r in enumerate(recent)]
    cracks = np.array([[0.02, 0.03]] * 8)  # (samples, tails)
    kwargs = {"samples": 8, "seed": 0, "bands": True}
    both = sample_risk(PHYSICS, None, cracks, futures, [2.0, 2.0], 200, **kwargs)
    alone = sample_risk(PHYSICS, None, cracks[:, :1], futures[:1], [2.0], 200, **kwargs)
    assert both[0].prob_critical == alone[0].prob_critical
    assert both[0].band_m is not None and alone[0].band_m is not None
    np.testing.assert_array_equal(both[0].band_m, alone[0].band_m)
    assert both[0].band_m.shape == (3, 201)
    assert both[0].crack_now_m == pytest.approx((0.02, 0.02, 0.02), rel=1e-6)  # bands: float32
    # 300 MPa from 3 cm reaches 5 cm within 400 flights; the first tail does not
    assert both[1].prob_critical == 1.0 and both[0].prob_critical == 0.0
    assert np.isfinite(both[1].flights_to_critical[1]) and not np.isfinite(
        both[0].flights_to_critical[1]
    )


def test_crack_samples_of_growth_factors_alone_interpolate_a_marched_factor_grid() -> None:
    """Without weight draws each tail marches a grid of factors over its samples' range and
    every sample reads its crack from it: within 1e-5 (median, 1e-3 at most) of marching each
    sample, over a thesis fleet's 7,300-flight histories, a fleet-prior spread and a tail run
    past fracture."""
    fleet = generate_fleet(FleetConfig(aircraft_per_mix=2, seed=1))
    model = CrackGrowthModel(ModelSpec(kernel="physics"))
    loads = LoadHistory(torch.from_numpy(fleet.stress_range_mpa), torch.full((6,), 7300))
    initial = torch.full((6,), 0.005, dtype=torch.float64)
    gen = torch.Generator().manual_seed(3)
    z = 0.3 * torch.randn(200, 6, generator=gen, dtype=torch.float64)
    z[:, 5] = 0.05 * z[:, 5] + 1.2  # one tail well past a_crit: held
    got = crack_samples(model, None, loads, initial, samples=200, seed=0, growth_factor=z.exp())
    with torch.no_grad():
        marched = torch.stack(
            [
                model(loads.stress_range_mpa, loads.lengths, initial, z[k].exp())[:, -1]
                for k in range(200)
            ]
        )
    error = (got / marched - 1).abs()
    assert float(error.median()) < 1e-5 and float(error.max()) < 1e-3
    assert len(set(got[:, 3].tolist())) > 190  # each sample its own crack
    assert float(got[:, 5].min()) == model.spec.law.held_crack_m


def test_marks_report_the_bands_own_days_with_or_without_bands() -> None:
    recent = [np.array([150.0, 200.0, 120.0, 90.0]), np.array([180.0, 100.0])]
    futures = [
        fc.ResampledLoads([r], n, seed=i, block_flights=2)
        for i, (r, n) in enumerate(zip(recent, (80, 100), strict=True))
    ]  # 40 days at 2 and 2.5 flights a day
    cracks = np.array([[0.01, 0.02]] * 8)  # (samples, tails)
    marks = [[5, 40], [0, 30]]
    kwargs = {"samples": 8, "seed": 0, "marks": marks}
    banded = sample_risk(PHYSICS, None, cracks, futures, [2.0, 2.5], 40, bands=True, **kwargs)
    plain = sample_risk(PHYSICS, None, cracks, futures, [2.0, 2.5], 40, bands=False, **kwargs)
    for tail, days in enumerate(marks):
        band = banded[tail].band_m
        assert band is not None and plain[tail].band_m is None
        np.testing.assert_array_equal(banded[tail].marks_m, band[:, days])
        np.testing.assert_array_equal(plain[tail].marks_m, band[:, days])
    assert (banded[0].marks_m[:, 1] > banded[0].marks_m[:, 0]).all()  # the crack grows
    with pytest.raises(ValueError, match="marks"):
        sample_risk(
            PHYSICS,
            None,
            cracks,
            futures,
            [2.0, 2.5],
            40,
            bands=False,
            samples=8,
            seed=0,
            marks=[[41], [0]],
        )
