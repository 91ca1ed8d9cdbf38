"""`fleetpinn spectrum` turns stress histories into the cycle file; the upload takes that file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import rainflow
from fastapi.testclient import TestClient
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.cli import main
from app.config import Settings
from app.db import make_engine
from app.tables import FlightBlock, SpectrumBlock
from model.records import read_table, write_table

HISTORY = [-8.0, 62.0, 40.0, 88.0, 55.0, 70.0, -5.0]


def _histories(path: Path, flights: int = 3) -> pd.DataFrame:
    rows = []
    for tail in ("N001", "N002"):
        for f in range(flights):
            for point in HISTORY:
                rows.append(
                    {
                        "tail": tail,
                        "flight_id": f"F{f + 1}",
                        "flown_at": f"2025-01-0{f + 1}T06:00:00Z",
                        "stress_mpa": point * (1 + 0.1 * f),
                        "mission": "M1",
                    }
                )
    frame = pd.DataFrame(rows)
    write_table(frame, path)
    return frame


def test_spectrum_counts_each_flight_as_the_library_does(tmp_path, capsys) -> None:
    _histories(tmp_path / "histories.csv")
    out = tmp_path / "cycles.csv"
    assert (
        main(["spectrum", "--histories", str(tmp_path / "histories.csv"), "--out", str(out)]) == 0
    )
    assert "flights" in capsys.readouterr().out
    cycles = read_table(out)
    assert list(cycles.columns) == [
        "tail",
        "flight_id",
        "flown_at",
        "stress_range_mpa",
        "load_ratio",
        "count",
        "mission",
    ]
    first = cycles[(cycles["tail"] == "N002") & (cycles["flight_id"] == "F3")]
    library = [
        c for c in rainflow.extract_cycles([p * 1.2 for p in HISTORY]) if c[1] + c[0] / 2 > 0
    ]
    assert first["count"].astype(float).tolist() == [c[2] for c in library]
    assert first["stress_range_mpa"].astype(float).tolist() == pytest.approx(
        [c[0] for c in library]
    )


@pytest.mark.parametrize(
    ("value", "reason"), [("nan", "finite"), ("abc", "finite"), (None, "at least 2 points")]
)
def test_a_bad_history_exits_2_naming_the_flight_and_column(
    tmp_path, capsys, value, reason
) -> None:
    frame = _histories(tmp_path / "ok.csv")
    if value is None:  # flight F2 of N001 keeps one point
        frame = frame[~((frame["tail"] == "N001") & (frame["flight_id"] == "F2"))].copy()
        extra = {"tail": "N001", "flight_id": "F2", "flown_at": "2025-01-02T06:00:00Z"}
        frame = pd.concat([frame, pd.DataFrame([{**extra, "stress_mpa": 5.0, "mission": "M1"}])])
    else:
        frame = frame.astype({"stress_mpa": object})
        frame.iloc[9, frame.columns.get_loc("stress_mpa")] = value
    frame.to_csv(tmp_path / "bad.csv", index=False)
    out = tmp_path / "cycles.csv"
    assert main(["spectrum", "--histories", str(tmp_path / "bad.csv"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "stress_mpa" in err and reason in err
    if value is None:
        assert "flight 'F2' of 'N001'" in err
    assert not out.exists()


def test_the_cycle_file_uploads_with_its_cycles(
    client: TestClient, settings: Settings, tmp_path
) -> None:
    _histories(tmp_path / "histories.csv")
    out = tmp_path / "cycles.csv"
    assert (
        main(["spectrum", "--histories", str(tmp_path / "histories.csv"), "--out", str(out)]) == 0
    )
    with out.open("rb") as handle:
        answer = client.post("/flights/upload", files={"file": ("cycles.csv", handle, "text/csv")})
    assert answer.status_code == 201, answer.text
    assert answer.json() == {"inserted": 6, "duplicates": 0, "aircraft_created": 2}
    law = settings.law()
    cycles = read_table(out)
    mine = cycles[(cycles["tail"] == "N001") & (cycles["flight_id"] == "F1")].astype(
        {"stress_range_mpa": float, "count": float}
    )
    expected = float(((mine["stress_range_mpa"] ** law.m) * mine["count"]).sum() ** (1 / law.m))
    stored = client.get("/aircraft/N001/flights/F1").json()["stress_range_mpa"]
    assert stored == pytest.approx(expected, rel=1e-12)
    engine = make_engine(settings.database_url)
    with Session(engine) as session:
        assert session.scalar(select(func.count()).select_from(FlightBlock)) == 6
        # one block per tail of the upload
        assert session.scalar(select(func.count()).select_from(SpectrumBlock)) == 2
    engine.dispose()


def test_a_cycle_file_whose_flight_rows_disagree_is_422_and_stores_nothing(
    client: TestClient, settings: Settings, tmp_path
) -> None:
    _histories(tmp_path / "histories.csv")
    out = tmp_path / "cycles.csv"
    assert (
        main(["spectrum", "--histories", str(tmp_path / "histories.csv"), "--out", str(out)]) == 0
    )
    cycles = read_table(out)
    cycles.loc[4, "flown_at"] = "2025-02-01T00:00:00Z"  # one cycle of N001's F2 moved
    cycles.loc[7, "load_ratio"] = 1.2
    for broken, column in ((cycles.iloc[:6], "flown_at"), (cycles.iloc[6:], "load_ratio")):
        broken.to_csv(tmp_path / "bad.csv", index=False)
        with (tmp_path / "bad.csv").open("rb") as handle:
            answer = client.post("/flights/upload", files={"file": ("bad.csv", handle, "text/csv")})
        assert answer.status_code == 422, answer.text
        assert answer.json()["column"] == column
    assert client.get("/aircraft?limit=5").json()["total"] == 0
    engine = make_engine(settings.database_url)
    with Session(engine) as session:
        assert session.scalar(select(func.count()).select_from(SpectrumBlock)) == 0
    engine.dispose()


def test_fit_learns_walkers_gamma_from_a_cycle_file_and_predict_reads_it(tmp_path) -> None:
    """The offline fit refits the law to the recorded cycles: Walker's gamma from the cycle
    file of a small spectra fleet whose tails change routes (error-free inspections), and
    predict marches the same file under the fitted law."""
    from model import artifacts
    from model.fleet import FleetConfig, inspect_at
    from model.physics import ParisLaw
    from model.spectra_fleet import SpectraFleetConfig, generate_spectra_fleet

    config = FleetConfig(
        aircraft_per_mix=10, years=3, flights_per_day=2, law=ParisLaw(c=7.5e-11), seed=3
    )
    spectra = generate_spectra_fleet(SpectraFleetConfig(config, gamma=0.6, switch_year=1.5))
    fleet = spectra.fleet
    flights = fleet.flights_frame()
    count = spectra.cycles.count.numpy().reshape(len(flights), -1)
    flown = count > 0
    per_flight = flown.sum(axis=1)
    cycles = pd.DataFrame(
        {
            "tail": np.repeat(flights["tail"].to_numpy(), per_flight),
            "flight_id": np.repeat(flights["flight_id"].to_numpy(), per_flight),
            "flown_at": np.repeat(flights["flown_at"].to_numpy(), per_flight),
            "stress_range_mpa": spectra.cycles.stress_range_mpa.numpy().reshape(len(flights), -1)[
                flown
            ],
            "load_ratio": spectra.cycles.load_ratio.numpy().reshape(len(flights), -1)[flown],
            "count": count[flown],
        }
    )
    write_table(cycles, tmp_path / "cycles.csv")
    fpy = config.flights_per_year
    sample = inspect_at(fleet, np.arange(0, fleet.size, 2), np.array([fpy, 2 * fpy, 3 * fpy]))
    write_table(fleet.inspections_frame(sample), tmp_path / "inspections.csv")
    files = [
        "--flights",
        str(tmp_path / "cycles.csv"),
        "--inspections",
        str(tmp_path / "inspections.csv"),
    ]
    out = tmp_path / "m.pt"
    argv = ["fit", *files, "--out", str(out), "--kernel", "physics", "--growth-law", "walker"]
    assert main([*argv, "--learn-paris"]) == 0
    model, metrics = artifacts.load(out)
    assert model.spec.growth_law == "walker"
    assert abs(metrics["growth_law"]["gamma"] - 0.6) < 0.05
    assert main(["predict", "--model", str(out), *files[:2], "--out", str(tmp_path / "p.csv")]) == 0
    predicted = read_table(tmp_path / "p.csv")
    final = predicted.groupby("tail")["crack_length_m"].last().astype(float).to_numpy()
    truth = fleet.crack_length_m[:, -1]
    assert float(np.median(np.abs(final / truth - 1))) < 0.02
