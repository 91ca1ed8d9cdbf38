"""Several control points per aircraft: upload once, retrain one job per location, forecast each.

    .venv/bin/python -m benchmarks.locations                      # 300 tails x 4 locations
    .venv/bin/python -m benchmarks.locations --aircraft-per-mix 5 --workers 1   # a smoke run

A hidden fleet: the thesis fleet (3 x --aircraft-per-mix tails, 5 years = 7,300 flights, growth
scatter 0.25 across tails) recorded once per flight (the far-field stress range), and four
locations that see it differently: each its own stress transfer factor, true geometry factor
(a constant times a discrepancy growing with crack length, which the catalogue does not know),
initial and critical crack, its own growth scatter draw (material) and its inspection method's
sizing error.  Every tail is inspected at each location at years 2 and 4 (two rounds, 2,400
inspections at 300 tails); inspections of cracks already past the location's a_crit are left
out (the part would have been replaced).

Timed on the service's own paths, a fresh SQLite file: the flights upload (app.services.ingest,
once for all locations), then for each --workers count a retrain of every location (one job per
location, app.services.retrain.enqueue_retrains) run by that many `fleetpinn worker --once`
processes, from the enqueue until every job finished.  Then every (tail, location)'s forecast
through app.services.forecast.forecast_tail is scored against the truth after the last flight
(one year past the latest inspection), per location, on tails whose true crack is below a_crit:
p50 |error| (median, p95), [p05, p95] coverage and median relative width.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from sqlalchemy import select

from app.config import Settings
from app.db import make_engine, make_session_factory
from app.migrate import upgrade
from app.services import audit, ingest, locations, retrain
from app.services.forecast import forecast_tail
from app.tables import Job
from model.fleet import DISCREPANCY_20PCT, FleetConfig, generate_fleet, simulate_cracks
from model.physics import ParisLaw
from model.runtime import configure_threads

BENCH = audit.local("benchmark")
YEARS_INSPECTED = (2, 4)
# `fleetpinn worker --once` from this checkout (the console script may name another)
_WORKER = "import sys; from app.cli import main; sys.exit(main(sys.argv[1:]))"


@dataclass(frozen=True)
class Place:
    """A location of the hidden fleet: its catalogue entry and the truth it does not say."""

    name: str
    entry: dict[str, Any]  # PUT /locations body (the default location: none)
    discrepancy: float  # beta of the true F(a) = F (1 + beta (a - a0) / (a_crit - a0))
    sizing_sd: float  # sizing error of its inspection method (ln measured - ln true)
    seed: int


PLACES = (
    Place("default", {}, DISCREPANCY_20PCT, 0.04, 0),
    Place(
        "wing-splice",
        {
            "stress_factor": 1.08,
            "initial_crack_m": 0.004,
            "critical_crack_m": 0.04,
            "sizing_relative_sd": 0.05,
            "pod_a50_m": 0.0015,
            "pod_a90_m": 0.0025,
            "inspection_method": "eddy current",
        },
        0.3,
        0.05,
        1,
    ),
    Place(
        "lap-joint",
        {
            "stress_factor": 0.92,
            "stress_factor_by_mission": {"M3": 1.0},
            "initial_crack_m": 0.005,
            "critical_crack_m": 0.045,
            "sizing_relative_sd": 0.03,
            "inspection_method": "ultrasonic",
        },
        0.1,
        0.03,
        2,
    ),
    Place(
        "bulkhead",
        {
            "stress_factor": 1.0,
            "geometry_factor": 1.05,
            "initial_crack_m": 0.004,
            "critical_crack_m": 0.035,
            "sizing_relative_sd": 0.04,
            "inspection_method": "visual + eddy current",
        },
        0.2,
        0.04,
        3,
    ),
)


def _truth(fleet: Any, place: Place, settings: Settings) -> np.ndarray:
    """(tails, flights + 1) true crack at the location: its local loads, its physics, its own
    growth scatter draw (material) and a discrepancy the catalogue does not know."""
    entry, base = place.entry, settings.law()
    law = ParisLaw(
        c=base.c,
        m=base.m,
        geometry_factor=entry.get("geometry_factor", base.geometry_factor),
        initial_crack_m=entry.get("initial_crack_m", base.initial_crack_m),
        critical_crack_m=entry.get("critical_crack_m", base.critical_crack_m),
    )
    blank = dict.fromkeys(locations.StoredLocation.__dataclass_fields__)
    location = locations.StoredLocation(
        **{
            **blank,
            "stress_factor": float(entry.get("stress_factor", 1.0)),
            "stress_factor_by_mission": entry.get("stress_factor_by_mission"),
        }
    )
    missions = pd.Series(np.asarray([f"M{m}" for m in range(4)])[fleet.mission.reshape(-1)])
    local = locations.scaled(fleet.stress_range_mpa.reshape(-1), missions, location)
    local = local.reshape(fleet.stress_range_mpa.shape)  # (tails, flights)
    growth = np.exp(0.25 * np.random.default_rng(100 + place.seed).standard_normal(fleet.size))
    return simulate_cracks(local, law, place.discrepancy, growth)


def _inspections(fleet: Any, truth: np.ndarray, place: Place, critical: float) -> pd.DataFrame:
    """Every tail at years 2 and 4, with the method's sizing error; cracks past a_crit left out."""
    fpy = fleet.config.flights_per_year
    rng = np.random.default_rng(10 + place.seed)
    rows = []
    for year in YEARS_INSPECTED:
        step = year * fpy
        true = truth[:, step]
        measured = true * np.exp(place.sizing_sd * rng.standard_normal(fleet.size))
        keep = true < critical
        at = fleet.flown_at[step - 1] + pd.Timedelta(minutes=30)
        rows.append(
            pd.DataFrame(
                {
                    "tail": np.asarray(fleet.tails)[keep],
                    "inspection_id": f"{place.name}-Y{year}",
                    "inspected_at": at,
                    "crack_length_m": measured[keep],
                    "location": place.name,
                }
            )
        )
    return pd.concat(rows, ignore_index=True)


def _retrain_with(workers: int, settings: Settings, factory: Any, env: dict[str, str]) -> float:
    """Seconds from queueing one retrain job per location to the last one finished, run by
    `workers` `fleetpinn worker --once` processes (started and ended here)."""
    with factory() as session:
        _, queued = retrain.enqueue_retrains(session, {}, actor=BENCH)
    started = time.perf_counter()
    procs = [
        subprocess.Popen([sys.executable, "-c", _WORKER, "worker", "--once"], env=env)
        for _ in range(workers)
    ]
    for proc in procs:
        proc.wait()
    seconds = time.perf_counter() - started
    with factory() as session:
        rows = session.execute(
            select(Job.id, Job.status, Job.error, Job.result).where(Job.id.in_(queued.values()))
        ).all()
    for job_id, status, error, result in rows:
        name = next(n for n, j in queued.items() if j == job_id)
        outcome = (result or {}).get("outcome")
        print(f"  {name}: {status} {outcome or ''} {error or ''}".rstrip())
    return seconds


def _scores(
    factory: Any, fleet: Any, place: Place, truth: np.ndarray, settings: Settings, critical: float
) -> dict[str, float]:
    """The service's forecast of each tail at the location against the truth after the last
    flight, on tails whose true crack is below a_crit."""
    p05, p50, p95, true = [], [], [], []
    as_of = settings.today()
    with factory() as session:
        for i, tail in enumerate(fleet.tails):
            now = float(truth[i, -1])
            if now >= critical:
                continue
            result = forecast_tail(
                session,
                tail,
                horizon_days=settings.forecast_horizon_days,
                settings=settings,
                as_of=as_of,
                location=place.name,
            )
            band = result.risk.crack_now
            p05.append(band[0] if band[0] is not None else np.inf)
            p50.append(band[1] if band[1] is not None else np.inf)
            p95.append(band[2] if band[2] is not None else np.inf)
            true.append(now)
    t, lo, mid, hi = (np.asarray(v, dtype=np.float64) for v in (true, p05, p50, p95))
    err = np.abs(mid / t - 1)
    return {
        "tails": len(t),
        "p50_median_pct": 100 * float(np.median(err)),
        "p50_p95_pct": 100 * float(np.quantile(err, 0.95)),
        "coverage_90": float(np.mean((lo <= t) & (t <= hi))),
        "width_90_pct": 100 * float(np.median((hi - lo) / mid)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--aircraft-per-mix", type=int, default=100)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    configure_threads()
    fleet = generate_fleet(
        FleetConfig(
            aircraft_per_mix=args.aircraft_per_mix,
            discrepancy=DISCREPANCY_20PCT,
            growth_scatter=0.25,
            seed=args.seed,
        )
    )
    with tempfile.TemporaryDirectory() as tmp:
        as_of = (fleet.flown_at[-1] + pd.Timedelta(days=1)).date()
        url = f"sqlite:///{Path(tmp) / 'bench.db'}"
        env = {
            **os.environ,
            "FLEETPINN_DATABASE_URL": url,
            "FLEETPINN_AS_OF": as_of.isoformat(),
            "FLEETPINN_MAX_CRACK_LENGTH_M": "1.0",
            "OMP_NUM_THREADS": "1",
        }
        settings = Settings(database_url=url, as_of=as_of, max_crack_length_m=1.0)
        upgrade(url)
        factory = make_session_factory(make_engine(url))
        frame = fleet.flights_frame()
        with factory() as session:
            started = time.perf_counter()
            ingest.ingest_flights(
                session, frame, source="fleet", create_tails=True, actor=BENCH, settings=settings
            )
            upload = time.perf_counter() - started
        print(
            f"upload {len(frame):,} flights ({fleet.size} tails x {fleet.config.flights}), "
            f"stored once for {len(PLACES)} locations: {upload:.1f} s"
        )
        truths, criticals, count = {}, {}, 0
        for place in PLACES:
            with factory() as session:
                if place.entry:
                    locations.put_location(
                        session, place.name, place.entry, actor=BENCH, settings=settings
                    )
            truths[place.name] = _truth(fleet, place, settings)
            criticals[place.name] = place.entry.get("critical_crack_m", settings.critical_crack_m)
            found = _inspections(fleet, truths[place.name], place, criticals[place.name])
            count += len(found)
            with factory() as session:
                ingest.ingest_inspections(
                    session, found, source=place.name, actor=BENCH, settings=settings
                )
        print(f"{count:,} inspections, two rounds per location")
        for workers in args.workers:
            seconds = _retrain_with(workers, settings, factory, env)
            print(f"retrain of {len(PLACES)} locations with {workers} worker(s): {seconds:.1f} s")
        print("| location | tails below a_crit | p50 median | p50 p95 | [p05, p95] holds | width |")
        print("|---|---:|---:|---:|---:|---:|")
        for place in PLACES:
            s = _scores(factory, fleet, place, truths[place.name], settings, criticals[place.name])
            print(
                f"| {place.name} | {s['tails']} | {s['p50_median_pct']:.2f} % | "
                f"{s['p50_p95_pct']:.2f} % | {100 * s['coverage_90']:.0f} % | "
                f"{s['width_90_pct']:.1f} % |"
            )


if __name__ == "__main__":
    main()
