"""An alloy of the materials table by name, and Walker's law, in the settings and `fleetpinn fit`."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from app.cli import main
from app.config import Settings
from model import artifacts
from model.fleet import FleetConfig, generate_fleet, scheduled_inspection
from model.materials import material
from model.records import write_table


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
    """No alloy of the table has NASGRO terms yet: the law is named, and refused with a reason."""
    argv = ["fit", "--flights", str(tmp_path / "f.csv"), "--inspections", str(tmp_path / "i.csv")]
    argv += ["--out", str(tmp_path / "m.pt"), "--growth-law", "nasgro", "--material", "2024-T3"]
    assert main(argv) == 2
    assert "--growth-law nasgro needs a --material whose row has NASGRO terms" in (
        capsys.readouterr().err
    )
    with pytest.raises(ValidationError, match="growth_law nasgro needs a material"):
        Settings(growth_law="nasgro")
