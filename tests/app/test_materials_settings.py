"""An alloy of the materials table by name, and Walker's law, in the settings and `fleetpinn fit`."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from pydantic import ValidationError

from app.cli import main
from app.config import Settings, get_settings
from model import artifacts
from model.fleet import FleetConfig, generate_fleet, scheduled_inspection
from model.materials import material
from model.records import write_table
from tests.materials_values import TEST_2024, TEST_A, TEST_B, nasgro_euler, write_materials


def test_settings_take_an_alloy_by_name_and_keep_the_structures_geometry() -> None:
    law = Settings(material="2024-T3", critical_crack_m=0.04, growth_law="walker").law()
    row = material("2024-T3")
    assert (law.c, law.m, law.gamma) == (row.c, row.m, row.gamma)
    assert law.critical_crack_m == 0.04
    assert Settings(walker_gamma=0.5).law().gamma == 0.5
    with pytest.raises(ValidationError, match="unknown material 'A356'"):
        Settings(material="A356")
    with pytest.raises(ValidationError, match="walker_gamma"):
        Settings(walker_gamma=1.5)
    with pytest.raises(ValidationError, match="growth_law"):
        Settings(growth_law="forman")


def test_fit_takes_a_material_and_the_walker_law(tmp_path) -> None:
    fleet = generate_fleet(FleetConfig(aircraft_per_mix=3, years=1))
    write_table(fleet.flights_frame(), tmp_path / "flights.csv")
    write_table(
        fleet.inspections_frame(scheduled_inspection(fleet, 5, "uniform-coverage")),
        tmp_path / "inspections.csv",
    )
    out = tmp_path / "m.pt"
    argv = [
        "fit",
        "--flights",
        str(tmp_path / "flights.csv"),
        "--inspections",
        str(tmp_path / "inspections.csv"),
    ]
    argv += [
        "--out",
        str(out),
        "--kernel",
        "physics",
        "--material",
        "7075-T6",
        "--growth-law",
        "walker",
    ]
    assert main(argv) == 0
    model, metrics = artifacts.load(out)
    assert model.spec.growth_law == "walker"
    assert (model.spec.law.c, model.spec.law.gamma) == (material("7075-T6").c, 0.641)
    assert metrics["growth_law"] == {"name": "walker", "gamma": 0.641}


def test_fit_refuses_the_nasgro_law_without_its_terms(tmp_path, capsys) -> None:
    """No alloy of the shipped table has NASGRO terms: without a materials file that gives them
    the law is refused with a reason."""
    argv = ["fit", "--flights", str(tmp_path / "f.csv"), "--inspections", str(tmp_path / "i.csv")]
    argv += ["--out", str(tmp_path / "m.pt"), "--growth-law", "nasgro", "--material", "2024-T3"]
    assert main(argv) == 2
    assert "--growth-law nasgro needs a --material whose row has NASGRO terms" in (
        capsys.readouterr().err
    )
    with pytest.raises(ValidationError, match="growth_law nasgro needs a material"):
        Settings(growth_law="nasgro")


def _fleet_files(folder: Path) -> tuple[Path, Path]:
    fleet = generate_fleet(FleetConfig(aircraft_per_mix=1, years=1))
    write_table(fleet.flights_frame(), folder / "flights.csv")
    inspected = scheduled_inspection(fleet, 2, "uniform-coverage")
    write_table(fleet.inspections_frame(inspected), folder / "inspections.csv")
    return folder / "flights.csv", folder / "inspections.csv"


def test_fit_and_predict_the_nasgro_law_from_a_users_materials_file(tmp_path: Path) -> None:
    """The NASGRO terms come from the user's file (TEST VALUES): the model file keeps them, so
    predict marches the NASGRO law without the file."""
    materials_file = write_materials(tmp_path / "ours.csv", TEST_A, TEST_B)
    flights, inspections = _fleet_files(tmp_path)
    out = tmp_path / "m.pt"
    argv = ["fit", "--flights", str(flights), "--inspections", str(inspections), "--out", str(out)]
    argv += ["--kernel", "physics", "--growth-law", "nasgro", "--material", "TEST-NASGRO-A"]
    assert main([*argv, "--materials-file", str(materials_file)]) == 0
    model, metrics = artifacts.load(out)
    row = material("TEST-NASGRO-A", materials_file)
    assert model.spec.growth_law == "nasgro" and metrics["growth_law"]["name"] == "nasgro"
    assert (model.spec.law.c, model.spec.law.m, model.spec.law.nasgro) == (row.c, row.m, row.nasgro)
    predicted = tmp_path / "pred.csv"
    argv = ["predict", "--model", str(out), "--flights", str(flights), "--out", str(predicted)]
    assert main(argv) == 0
    answer = pd.read_csv(predicted).set_index("tail")["crack_length_m"]
    recorded = pd.read_csv(flights)
    for tail in answer.index[:2]:
        stresses = recorded.loc[recorded["tail"] == tail, "stress_range_mpa"]
        assert answer[tail] == pytest.approx(nasgro_euler(row, stresses, 0.005), rel=1e-9)


def test_fit_refuses_a_bad_materials_file_in_one_line_naming_file_row_and_column(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = write_materials(tmp_path / "bad.csv", TEST_A.replace(",0.5,1.0,2.0,", ",-0.5,1.0,2.0,"))
    argv = ["fit", "--flights", str(tmp_path / "f.csv"), "--inspections", str(tmp_path / "i.csv")]
    argv += ["--out", str(tmp_path / "m.pt"), "--growth-law", "nasgro"]
    assert main([*argv, "--material", "TEST-NASGRO-A", "--materials-file", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err == (
        f"fleetpinn fit: error: materials file {bad}: line 3, material 'TEST-NASGRO-A', "
        "column 'nasgro_p': must be >= 0, got -0.5\n"
    )
    good = write_materials(tmp_path / "good.csv", TEST_A)
    assert main([*argv, "--material", "TEST-NASGRO-C", "--materials-file", str(good)]) == 2
    assert "--material: unknown material 'TEST-NASGRO-C'; known: 2024-T3" in (
        capsys.readouterr().err
    )
    assert main([*argv, "--material", "TEST-NASGRO-A"]) == 2  # the file not named: unknown
    assert "unknown material 'TEST-NASGRO-A'" in capsys.readouterr().err


def test_settings_take_a_users_materials_file_and_refuse_a_bad_one_at_start_up(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    ours = write_materials(tmp_path / "ours.csv", TEST_A, TEST_2024)
    settings = Settings(materials_file=ours, material="TEST-NASGRO-A", growth_law="nasgro")
    assert settings.law().nasgro == material("TEST-NASGRO-A", ours).nasgro
    # a shipped name in the file: the file's row replaces the shipped one whole
    replaced = Settings(materials_file=ours, material="2024-T3", growth_law="nasgro").law()
    assert (replaced.c, replaced.m, replaced.gamma) == (2.0e-11, 3.3, 0.7)
    assert Settings(material="2024-T3").law().c == material("2024-T3").c
    bad = write_materials(tmp_path / "bad.csv", TEST_A.replace("6.7e-11", "6.7e-11x"))
    with pytest.raises(ValidationError, match="materials_file") as refused:
        Settings(materials_file=bad)
    assert (
        f"materials file {bad}: line 3, material 'TEST-NASGRO-A', column 'c_m_per_cycle': "
        "not a number: '6.7e-11x'"
    ) in str(refused.value)
    # the service's commands read it from FLEETPINN_MATERIALS_FILE and stop in one line
    monkeypatch.setenv("FLEETPINN_DATABASE_URL", f"sqlite:///{tmp_path / 'db.sqlite'}")
    monkeypatch.setenv("FLEETPINN_MATERIALS_FILE", str(bad))
    get_settings.cache_clear()
    try:
        assert main(["retrain"]) == 2
        err = capsys.readouterr().err.splitlines()[-1]
        assert err.startswith("fleetpinn retrain: error: setting FLEETPINN_MATERIALS_FILE: ")
        assert err.endswith("column 'c_m_per_cycle': not a number: '6.7e-11x'")
        monkeypatch.setenv("FLEETPINN_MATERIALS_FILE", str(ours))
        monkeypatch.setenv("FLEETPINN_GROWTH_LAW", "nasgro")
        get_settings.cache_clear()
        assert main(["retrain"]) == 2  # a check across settings names no one of them
        err = capsys.readouterr().err.splitlines()[-1]
        assert err.startswith("fleetpinn retrain: error: settings: Value error, growth_law nasgro")
        monkeypatch.setenv("FLEETPINN_MATERIAL", "TEST-NASGRO-A")
        get_settings.cache_clear()
        assert get_settings().law().nasgro == material("TEST-NASGRO-A", ours).nasgro
    finally:
        get_settings.cache_clear()
