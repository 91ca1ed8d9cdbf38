"""The service's retrain on stored cycles against one range per flight, measured in the same run.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.spectra_retrain --per-mix 20

The spectra fleet (model/spectra_fleet.py, Walker gamma 0.6) uploaded twice into fresh SQLite
files through the app in-process: as its cycle file, and as one damage-equivalent range per
flight (R ignored, today's input); a third of the tails inspected at years 2 and 4 with 4 %
sizing error; then each retrained by the service's own call (app.services.jobs.retrain.run_retrain,
Walker's law from gamma 1, C, m and gamma learned, the default kernel), wall and CPU time of
the whole job (history, fit, validation, the refill of the forecast cache).  The issue's goal:
the retrain on cycles within 1.5x of the one on single ranges.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any, cast

import numpy as np
import pandas as pd
from sqlalchemy.orm import Session

from app.config import Settings
from app.db import make_engine
from app.migrate import upgrade
from app.services.jobs.retrain import run_retrain
from model.fleet import FleetConfig, inspect_at
from model.spectra_fleet import SpectraFleet, SpectraFleetConfig, generate_spectra_fleet
from tests.app.conftest import serving


def _inspections(spectra: SpectraFleet) -> list[tuple[str, list[dict[str, Any]]]]:
    fleet = spectra.fleet
    fpy = fleet.config.flights_per_year
    chosen = np.arange(0, fleet.size, 3)
    sample = inspect_at(fleet, chosen, np.array([2 * fpy, 4 * fpy]), noise_sd=0.04, seed=1)
    frame = fleet.inspections_frame(sample)
    return [
        (
            str(tail),
            [
                {
                    "inspection_id": row.inspection_id,
                    "inspected_at": cast(pd.Timestamp, row.inspected_at).isoformat(),
                    "crack_length_m": row.crack_length_m,
                }
                for row in rows.itertuples()
            ],
        )
        for tail, rows in frame.groupby("tail")
    ]


def _retrain(folder: Path, name: str, flights: Path, spectra: SpectraFleet) -> dict[str, Any]:
    url = f"sqlite:///{folder / (name + '.db')}"
    upgrade(url)
    as_of = (spectra.fleet.flown_at[-1] + pd.Timedelta(days=1)).date()  # today: after the data
    settings = Settings(
        database_url=url,
        growth_law="walker",
        walker_gamma=1.0,
        learn_paris=True,
        run_worker=False,
        as_of=as_of,
        max_upload_rows=100_000_000,  # a fleet's cycle file: millions of rows
    )
    with serving(settings) as client:
        with flights.open("rb") as handle:
            answer = client.post("/flights/upload", files={"file": (flights.name, handle)})
        assert answer.status_code == 201, answer.text
        for tail, body in _inspections(spectra):
            answer = client.post(f"/aircraft/{tail}/inspections", json=body)
            assert answer.status_code == 201, answer.text
    engine = make_engine(url)
    wall, cpu = time.perf_counter(), time.process_time()
    with Session(engine) as session:
        result = run_retrain(
            session, job_id=None, params={}, settings=settings, progress=lambda *_: None
        )
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    engine.dispose()
    law = result["metrics"]["growth_law"]
    return {"wall_s": round(wall, 1), "cpu_s": round(cpu, 1), "gamma": round(law["gamma"], 3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-mix", type=int, default=20)
    args = parser.parse_args()
    spectra = generate_spectra_fleet(SpectraFleetConfig(FleetConfig(aircraft_per_mix=args.per_mix)))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        single = spectra.fleet.flights_frame()
        single["stress_range_mpa"] = spectra.paris_equivalent_mpa().reshape(-1)
        single_file, cycle_file = folder / "flights.parquet", folder / "cycles.parquet"
        single.to_parquet(single_file)
        spectra.cycles_frame().to_parquet(cycle_file)
        one = _retrain(folder, "single", single_file, spectra)
        cycles = _retrain(folder, "cycles", cycle_file, spectra)
    print(
        json.dumps(
            {
                "tails": 3 * args.per_mix,
                "single": one,
                "cycles": cycles,
                "ratio_wall": round(cycles["wall_s"] / one["wall_s"], 2),
                "ratio_cpu": round(cycles["cpu_s"] / one["cpu_s"], 2),
            }
        )
    )


if __name__ == "__main__":
    main()
