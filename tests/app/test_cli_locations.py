"""`fleetpinn fit` and `predict` on files that hold several control points' inspections: one
location at a time (`--location`), never the wing root's and the lug's cracks read as one."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from app.cli import main
from model import artifacts
from model.fleet import FleetConfig, generate_fleet, scheduled_inspection
from model.records import write_table

TINY = FleetConfig(aircraft_per_mix=3, years=1, discrepancy=1.0)


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    """Flights; the fleet's inspections at `wing`; the same plus `lug`'s (its cracks 1.3x)."""
    root = tmp_path_factory.mktemp("locations")
    fleet = generate_fleet(TINY)
    write_table(fleet.flights_frame(), root / "flights.csv")
    wing = fleet.inspections_frame(scheduled_inspection(fleet, 5, "uniform-coverage"))
    wing = wing.assign(location="wing")
    lug = wing.assign(location="lug", crack_length_m=wing["crack_length_m"] * 1.3)
    lug["inspection_id"] = "L-" + lug["inspection_id"].astype(str)
    write_table(wing, root / "wing.csv")
    write_table(pd.concat([wing, lug], ignore_index=True), root / "both.csv")
    return root / "flights.csv", root / "wing.csv", root / "both.csv"


def test_fit_refuses_several_locations_without_location_and_stores_nothing(
    files: tuple[Path, Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    flights, _, both = files
    out = tmp_path / "m.pt"
    argv = ["fit", "--flights", str(flights), "--inspections", str(both), "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "both.csv: column location names 2 locations (lug, wing)" in err
    assert "--location" in err and not out.exists()


def test_fit_at_a_location_is_the_fit_of_that_locations_own_file(
    files: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    """--location wing of the mixed file fits exactly what the wing-only file fits; and its
    --stress-factor is the recorded loads scaled (the fit's loads box says so)."""
    flights, wing, both = files
    base = ["fit", "--flights", str(flights), "--kernel", "physics", "--out"]
    assert (
        main([*base, str(tmp_path / "a.pt"), "--inspections", str(both), "--location", "wing"]) == 0
    )
    assert main([*base, str(tmp_path / "b.pt"), "--inspections", str(wing)]) == 0
    (_, a), (_, b) = artifacts.load(tmp_path / "a.pt"), artifacts.load(tmp_path / "b.pt")
    for key in ("inspections", "train_abs_pct_error_median", "train_abs_pct_error_max"):
        assert a[key] == b[key], key
    # a network kernel keeps the loads box its inputs are scaled by (the physics has none)
    learned = ["fit", "--flights", str(flights), "--inspections", str(wing), "--kernel"]
    learned += ["residual", "--out"]
    assert main([*learned, str(tmp_path / "c.pt"), "--stress-factor", "1.2"]) == 0
    assert main([*learned, str(tmp_path / "d.pt")]) == 0
    (model, _), (plain, _) = artifacts.load(tmp_path / "c.pt"), artifacts.load(tmp_path / "d.pt")
    assert model.spec.box is not None and plain.spec.box is not None
    top, top_plain = model.spec.box.stress_range_mpa[1], plain.spec.box.stress_range_mpa[1]
    assert top == pytest.approx(top_plain * 1.2)


def test_predict_refuses_several_locations_without_location(
    files: tuple[Path, Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    flights, wing, both = files
    model = tmp_path / "m.pt"
    fit = ["fit", "--flights", str(flights), "--inspections", str(wing), "--kernel", "physics"]
    assert main([*fit, "--out", str(model)]) == 0
    out = tmp_path / "p.csv"
    argv = ["predict", "--model", str(model), "--flights", str(flights), "--out", str(out)]
    assert main([*argv, "--inspections", str(both)]) == 2
    assert "names 2 locations (lug, wing)" in capsys.readouterr().err
    assert not out.exists()
    assert main([*argv, "--inspections", str(both), "--location", "lug"]) == 0
