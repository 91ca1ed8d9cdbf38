from __future__ import annotations

import numpy as np
import pytest
import torch

from model.fleet import (
    DISCREPANCY_20PCT,
    MISSION_MIXES,
    MISSION_STRESS_MPA,
    FleetConfig,
    continuous_monitoring,
    generate_fleet,
    scheduled_inspection,
    simulate_cracks,
    true_geometry_factor,
)
from model.geometry import GeometryTable
from model.hybrid import CrackGrowthModel, ModelSpec
from model.physics import ParisLaw, paris_closed_form
from model.record_validation import validate_flights, validate_inspections
from model.training_data import assemble

SMALL = FleetConfig(aircraft_per_mix=10, years=1, flights_per_day=2)


@pytest.fixture(scope="module")
def thesis_fleet():
    return generate_fleet()


def test_same_seed_same_fleet_other_seed_other_fleet():
    a, b = generate_fleet(SMALL), generate_fleet(SMALL)
    np.testing.assert_array_equal(a.stress_range_mpa, b.stress_range_mpa)
    np.testing.assert_array_equal(a.crack_length_m, b.crack_length_m)
    c = generate_fleet(FleetConfig(aircraft_per_mix=10, years=1, flights_per_day=2, seed=1))
    assert not np.array_equal(a.stress_range_mpa, c.stress_range_mpa)


def test_thesis_fleet_shape_and_mission_shares(thesis_fleet):
    fleet = thesis_fleet
    assert fleet.stress_range_mpa.shape == (300, 7300)
    assert fleet.crack_length_m.shape == (300, 7301)
    assert fleet.tails[:2] == ["N001", "N002"] and fleet.tails[-1] == "N300"
    assert str(fleet.flown_at[0]) == "2020-01-01 00:00:00+00:00"
    for i in (0, 1, 57, 100, 299):
        first, second = MISSION_MIXES[str(fleet.mix[i])]
        k = int(fleet.share_pct[i])
        assert k == i % 100
        assert (fleet.mission[i] == first).sum() == 73 * k
        assert (fleet.mission[i] == second).sum() == 7300 - 73 * k
    # shuffled, not flown in blocks: aircraft k = 50 of mix A flies M0 in both halves
    half = fleet.mission[50, :3650]
    assert 1500 < (half == 0).sum() < 2150


def test_scatter_is_mean_one_lognormal(thesis_fleet):
    nominal = np.asarray(MISSION_STRESS_MPA)[thesis_fleet.mission]
    ratio = thesis_fleet.stress_range_mpa / nominal
    assert abs(ratio.mean() - 1.0) < 1e-3
    assert np.log(ratio).std() == pytest.approx(thesis_fleet.config.stress_scatter, rel=0.01)


def test_year5_crack_span_matches_thesis(thesis_fleet):
    final = thesis_fleet.final_crack_m
    assert 0.0060 < final.min() < 0.0075
    assert 0.030 < final.max() < 0.037
    assert final.max() < thesis_fleet.config.law.critical_crack_m


def test_truth_is_the_physics_kernel_march():
    fleet = generate_fleet(SMALL)
    model = CrackGrowthModel(ModelSpec(kernel="physics"))
    with torch.no_grad():
        physics = model.trajectory(fleet.loads, method="sequential").numpy()
    np.testing.assert_allclose(fleet.crack_length_m, physics, rtol=1e-12)


def test_constant_stress_truth_matches_closed_form():
    law = ParisLaw()
    crack = simulate_cracks(np.full((1, 7300), 130.0), law)
    exact = float(paris_closed_form(law.initial_crack_m, 130.0, 7300.0, law))
    assert crack[0, -1] == pytest.approx(exact, rel=1e-3)


def test_discrepancy_makes_physics_underpredict_by_about_20_percent(thesis_fleet):
    truth = generate_fleet(FleetConfig(discrepancy=DISCREPANCY_20PCT)).final_crack_m
    error = thesis_fleet.final_crack_m / truth - 1.0  # physics-only prediction vs truth
    assert -0.25 < error.min() < -0.15
    assert (error <= 0).all()


@pytest.mark.parametrize(
    ("period", "per_aircraft"), [("yearly", 5), ("monthly", 60), ("weekly", 260), ("daily", 1825)]
)
def test_continuous_monitoring_counts_match_table_4_2(thesis_fleet, period, per_aircraft):
    sample = continuous_monitoring(thesis_fleet, period)
    assert sample.aircraft.tolist() == list(range(0, 300, 5))
    assert len(sample.observations.flights) == 60 * per_aircraft
    assert sample.loads.stress_range_mpa.shape == (60, 7300)
    obs = sample.observations
    expected = thesis_fleet.crack_length_m[sample.aircraft[obs.aircraft].numpy(), obs.flights]
    np.testing.assert_array_equal(obs.crack_length_m.numpy(), expected)


@pytest.mark.parametrize("count", [5, 15, 30, 60])
def test_scheduled_inspection_selections(thesis_fleet, count):
    final = thesis_fleet.final_crack_m
    third = np.sort(final)[[99, 200]]
    samples = {
        s: scheduled_inspection(thesis_fleet, count, s)
        for s in ("biased-small", "true-distribution", "uniform-coverage", "biased-large")
    }
    for sample in samples.values():
        assert len(sample.aircraft) == len(set(sample.aircraft.tolist())) == count
        assert sample.observations.flights.tolist() == [7300] * count
    assert (final[samples["biased-small"].aircraft] <= third[0]).all()
    assert (final[samples["biased-large"].aircraft] >= third[1]).all()
    uniform = final[samples["uniform-coverage"].aircraft]
    assert uniform.min() == final.min() and uniform.max() == final.max()
    # evenly spread: no gap much wider than the target spacing or the fleet's own widest gap
    spacing = max((final.max() - final.min()) / (count - 1), np.diff(np.sort(final)).max())
    assert np.diff(np.sort(uniform)).max() < 2.5 * spacing
    assert np.median(uniform) > np.median(final[samples["true-distribution"].aircraft])


def test_noise_is_multiplicative_with_given_sd(thesis_fleet):
    clean = continuous_monitoring(thesis_fleet, "daily")
    noisy = continuous_monitoring(thesis_fleet, "daily", noise_sd=0.05, seed=3)
    log_ratio = np.log(
        noisy.observations.crack_length_m.numpy() / clean.observations.crack_length_m.numpy()
    )
    assert float(log_ratio.std()) == pytest.approx(0.05, rel=0.02)


def test_bad_scenario_arguments_are_rejected():
    fleet = generate_fleet(SMALL)
    with pytest.raises(ValueError, match="selection"):
        scheduled_inspection(fleet, 5, "random")
    with pytest.raises(ValueError, match="count"):
        scheduled_inspection(fleet, 31, "true-distribution")
    with pytest.raises(ValueError, match="period"):
        continuous_monitoring(fleet, "hourly")


def test_long_format_round_trips_through_records():
    fleet = generate_fleet(SMALL)
    sample = scheduled_inspection(fleet, 6, "uniform-coverage")
    monitor = continuous_monitoring(fleet, "monthly", aircraft=4)
    data = assemble(
        validate_flights(fleet.flights_frame()),
        validate_inspections(fleet.inspections_frame(monitor)),
    )
    assert data.tails == fleet.tails
    torch.testing.assert_close(data.loads.stress_range_mpa, fleet.loads.stress_range_mpa)
    obs = monitor.observations
    assert data.observations.flights.tolist() == obs.flights.tolist()
    assert data.observations.aircraft.tolist() == monitor.aircraft[obs.aircraft].tolist()
    inspections = fleet.inspections_frame(sample)
    assert inspections["tail"].tolist() == [fleet.tails[i] for i in sample.aircraft]


def test_a_falling_factor_and_a_table_truth_shape_the_cracks():
    """'fall' grows slower than the law; a table of the truth's F is read as the table says
    (one equal to 'linear' at its points gives linear's cracks), and a fall to F <= 0 is
    refused."""
    law = ParisLaw()
    stress = np.full((1, 7300), 120.0)
    plain = simulate_cracks(stress, law)[0, -1]
    assert simulate_cracks(stress, law, 0.15, geometry="fall")[0, -1] < plain
    cracks = np.linspace(law.initial_crack_m, law.critical_crack_m, 64)
    table = GeometryTable.of(cracks, true_geometry_factor(cracks, law, "linear", 0.2))
    linear = simulate_cracks(stress, law, 0.2, geometry="linear")[0, -1]
    assert simulate_cracks(stress, law, geometry=table)[0, -1] == pytest.approx(linear, rel=1e-4)
    with pytest.raises(ValueError, match="discrepancy < 1"):
        FleetConfig(geometry="fall", discrepancy=1.0)
