"""Several control points per aircraft: upload once, retrain one job per location, forecast each.

    .venv/bin/python -m benchmarks.locations                      # 300 tails x 4 locations
    .venv/bin/python -m benchmarks.locations --aircraft-per-mix 5 --workers 1   # a smoke run
    .venv/bin/python -m benchmarks.locations --geometry-table bulkhead --worst 10

A hidden fleet: the thesis fleet (3 x --aircraft-per-mix tails, 5 years = 7,300 flights recorded,
flown on for the forecast horizon, growth scatter 0.25 across tails) recorded once per flight
(the far-field stress range), and four
locations that see it differently: each its own stress transfer factor, true geometry factor
(a constant times a discrepancy growing with crack length, which the catalogue does not know),
initial and critical crack, its own growth scatter draw (material) and its inspection method's
sizing error (benchmarks/location_fleet.py).  Every tail is inspected at each location at years 2 and 4 (two rounds, 2,400
inspections at 300 tails); inspections of cracks already past the location's a_crit are left
out (the part would have been replaced).  --geometry-table NAME gives that location a part
whose F rises towards an edge (a finite-width secant factor, the entry's constant F at a0) in the truth
(still times its discrepancy), and its catalogue entry that F as a table over crack length (model.geometry.GeometryTable);
with --table-as-constant the entry gives only F at a0 (what the physics read before tables).
--known-discrepancy NAME (a diagnosis) gives that location's catalogue its true F(a), the
discrepancy included, as a table.

Timed on the service's own paths, a fresh SQLite file: the flights upload (app.services.records.ingest, once
for all locations), then for each --workers count a retrain of every location (one job per location,
app.services.jobs.retrain.enqueue_retrains) run by that many `fleetpinn worker --once` processes (numba's
cache warmed first, as an image's build does, its CPU printed apart), from the enqueue until every
job finished (each process imports the tree's code when it starts: the run stops where app/ or
model/ changed since it began, source_stamp).  Then every (tail, location)'s forecast through
app.services.forecasts.forecast.forecast_tail is scored against the truth after the last flight (one year past
the latest inspection), per location, on tails whose true crack is below a_crit: p50 |error|
(median, p95), [p05, p95] coverage and median relative width; and on the same tails P(critical) by
the forecast horizon's end (settings.forecast_horizon_days past the as-of date) against whether the
truth, flown on, reaches a_crit by then: tails that do and are flagged (P >= 0.5), false alarms and
the Brier score.  --worst N prints each location's N largest p50 errors with the tail's truth,
measurements and growth draw (benchmarks/location_errors.py); --oracle scores beside each location
what its data allow: the forecast of one that knew the location's true law, spread and sizing error
(benchmarks/location_oracle.py).
"""

from __future__ import annotations

import argparse
import hashlib
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from sqlalchemy import select

from app.config import Settings
from app.db import make_engine, make_session_factory
from app.migrate import upgrade
from app.services import audit
from app.services.forecasts.forecast import forecast_tail
from app.services.jobs import retrain
from app.services.records import ingest, locations
from app.tables import Job, Location, ModelVersion
from benchmarks import location_fleet as hidden
from benchmarks.location_errors import print_worst
from benchmarks.location_fleet import PLACES, YEARS_INSPECTED, YEARS_RECORDED
from benchmarks.location_oracle import oracle_rows
from model.fleet import DISCREPANCY_20PCT, Fleet, FleetConfig, generate_fleet, inspect_at
from model.runtime import configure_threads
from model.train import fit_crack_model

BENCH = audit.local("benchmark")
# `fleetpinn worker --once` from this checkout (the console script may name another)
_WORKER = "import sys; from app.cli import main; sys.exit(main(sys.argv[1:]))"


def source_stamp() -> str:
    """A SHA-256 over the service's files (app/ and model/, caches left out): what each
    `fleetpinn worker --once` process imports when it starts, minutes into a run."""
    root = Path(__file__).resolve().parent.parent
    digest = hashlib.sha256()
    for path in sorted(p for part in ("app", "model") for p in (root / part).rglob("*")):
        if path.is_file() and "__pycache__" not in path.parts:
            digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def _same_source(stamp: str) -> None:
    """Stop where the code changed since the run began (a merge or a checkout in this tree):
    the workers started since would train with other code than the first ones, and the run's
    figures would mix both (issue 20: a default path sd of 0.644 in one run and 0.850 in the
    next, the second's two-worker retrain on a commit merged while it ran)."""
    if source_stamp() != stamp:
        raise SystemExit(
            "app/ or model/ changed during the run: its retrains mixed two versions "
            "of the code; run it again on a tree nothing changes"
        )


def _compile_ahead(env: dict[str, str]) -> float:
    """CPU seconds of model.runtime.warm_up in a process of its own: it compiles into numba's
    on-disk cache every loop a retrain runs that this checkout has not compiled yet (as the
    image's build and a long-lived worker's start do), so the timed workers load them from it
    and a fresh checkout's one-off compile (~20-40 CPU s) is not counted as the retrain's."""
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    warm = "from model.runtime import warm_up; warm_up()"
    subprocess.run([sys.executable, "-c", warm], env=env, check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return after.ru_utime + after.ru_stime - used.ru_utime - used.ru_stime


def _retrain_with(
    workers: int, settings: Settings, factory: Any, env: dict[str, str]
) -> tuple[float, float]:
    """Seconds from queueing one retrain job per location to the last one finished, run by
    `workers` `fleetpinn worker --once` processes (started and ended here), and the CPU
    seconds those processes used (user and system: what other work on a shared machine
    changes least)."""
    with factory() as session:
        _, queued = retrain.enqueue_retrains(session, {}, actor=BENCH)
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    procs = [
        subprocess.Popen([sys.executable, "-c", _WORKER, "worker", "--once"], env=env)
        for _ in range(workers)
    ]
    for proc in procs:
        proc.wait()
    seconds = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - used.ru_utime - used.ru_stime
    with factory() as session:
        rows = session.execute(
            select(Job.id, Job.status, Job.error, Job.result).where(Job.id.in_(queued.values()))
        ).all()
    for job_id, status, error, result in rows:
        name = next(n for n, j in queued.items() if j == job_id)
        outcome = (result or {}).get("outcome")
        # why a version was not activated (a refusal by its gate, a candidate, superseded)
        why = "" if outcome in (None, "activated") else f"({result['reason']})"
        print(f"  {name}: {status} {outcome or ''} {why} {error or ''}".rstrip())
    return seconds, cpu


def _fitted(factory: Any) -> None:
    """Print what each location's active version chose: its kernel, the extrapolation beyond
    its measured cracks (a_s, trend), its fleet's growth spread and its path drift."""
    with factory() as session:
        rows = session.execute(
            select(Location.name, ModelVersion.training, ModelVersion.metrics)
            .join(ModelVersion, ModelVersion.location_id == Location.id)
            .where(ModelVersion.status == "active")
            .order_by(Location.id)
        ).all()
    for name, training, metrics in rows:
        beyond = metrics.get("extrapolation") or {}
        tracking = metrics.get("tracking") or {}
        choice = metrics.get("kernel_choice") or {}
        chosen = choice.get("chosen", training["kernel"])
        likelihoods = ", ".join(
            f"{k} {v:.1f}" for k, v in choice.get("held_out_log_likelihood", {}).items()
        )
        print(
            f"  {name}: kernel {chosen} (held-out log-likelihood {likelihoods or '-'}), "
            "measured cracks to "
            f"{1e3 * beyond.get('seen_crack_m', float('nan')):.1f} mm, trend beyond "
            f"{beyond.get('slope', float('nan')):.3f}, growth sd "
            f"{tracking.get('growth_sd', float('nan')):.3f}, path sd "
            f"{tracking.get('path_sd', float('nan')):.3f}"
        )


def _service_rows(
    factory: Any,
    fleet: Any,
    truth: np.ndarray,
    settings: Settings,
    critical: float,
    name: str,
    recorded: int,
    horizon_end: int,
) -> pd.DataFrame:
    """The service's forecast of each tail at the location, on tails whose true crack is below
    a_crit after the last recorded flight: its band after that flight and its P(critical) by
    the horizon's end (flight horizon_end), beside the truth at both."""
    rows = []
    as_of = settings.today()
    with factory() as session:
        for i, tail in enumerate(fleet.tails):
            now = float(truth[i, recorded])
            if now >= critical:
                continue
            result = forecast_tail(
                session,
                tail,
                horizon_days=settings.forecast_horizon_days,
                settings=settings,
                as_of=as_of,
                location=name,
            )
            band = [np.inf if b is None else b for b in result.risk.crack_now]
            rows.append(
                {
                    "index": i,
                    "tail": tail,
                    "true_m": now,
                    "p05_m": band[0],
                    "p50_m": band[1],
                    "p95_m": band[2],
                    "prob_critical": result.risk.prob_critical,
                    "reaches": bool(truth[i, horizon_end] >= critical),
                }
            )
    return pd.DataFrame(rows)


def _scores(frame: pd.DataFrame) -> dict[str, float]:
    """A location's rows (the service's or the oracle's) against the truth: p50 |error| (median,
    p95), [p05, p95] coverage and median relative width; tails that reach a_crit by the
    horizon's end and are flagged (P >= 0.5), false alarms, Brier.  Adds p50_error to frame."""
    t, lo, mid, hi = (frame[c].to_numpy(np.float64) for c in ("true_m", "p05_m", "p50_m", "p95_m"))
    err = np.abs(mid / t - 1)
    frame["p50_error"] = mid / t - 1
    reach, prob = frame["reaches"].to_numpy(), frame["prob_critical"].to_numpy(np.float64)
    flagged = prob >= 0.5
    return {
        "tails": len(t),
        "p50_median_pct": 100 * float(np.median(err)),
        "p50_p95_pct": 100 * float(np.quantile(err, 0.95)),
        "coverage_90": float(np.mean((lo <= t) & (t <= hi))),
        "width_90_pct": 100 * float(np.median((hi - lo) / mid)),
        "reach": int(reach.sum()),
        "flagged": int((flagged & reach).sum()),
        "false_alarms": int((flagged & ~reach).sum()),
        "brier": float(np.mean((prob - reach) ** 2)),
    }


def _print_scores(scores: dict[str, dict[str, float]], horizon: str) -> None:
    """The two tables of RESULTS.md: the crack after the last recorded flight, and P(critical)
    by the horizon's end, a row per location (and its oracle's)."""
    print("| location | tails below a_crit | p50 median | p50 p95 | [p05, p95] holds | width |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, s in scores.items():
        print(
            f"| {name} | {s['tails']} | {s['p50_median_pct']:.2f} % | "
            f"{s['p50_p95_pct']:.2f} % | {100 * s['coverage_90']:.0f} % | "
            f"{s['width_90_pct']:.1f} % |"
        )
    print(f"\nP(critical) by the horizon's end ({horizon}):")
    print("| location | reach a_crit | flagged | false alarms | Brier |")
    print("|---|---:|---:|---:|---:|")
    for name, s in scores.items():
        print(
            f"| {name} | {s['reach']} | {s['flagged']} | {s['false_alarms']} | {s['brier']:.4f} |"
        )


def _reference_fit(fleet: Fleet, settings: Settings) -> float:
    """Seconds of one plain fit of the shared model (model.train.fit_crack_model) on every
    tail's far-field crack at the inspection years, 4 % sizing error: the yardstick the
    retrain is read against in the same run (benchmarks.tracking_service's), since the hosts
    these goals were measured on have differed 2.7x."""
    years = np.array([year * fleet.config.flights_per_year for year in YEARS_INSPECTED])
    sample = inspect_at(fleet, np.arange(fleet.size), years, noise_sd=0.04, seed=1)
    started = time.perf_counter()
    fit_crack_model(sample.loads, sample.observations, law=settings.law())
    return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--aircraft-per-mix", type=int, default=100)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--seed", type=int, default=0)
    tabled = [p.name for p in PLACES if p.entry]
    parser.add_argument(
        "--geometry-table",
        choices=tabled,
        help="give this location's part an F rising towards an edge, as a catalogue table",
    )
    parser.add_argument(
        "--table-as-constant",
        action="store_true",
        help="the same part, its catalogue entry giving only F at a0 (the physics before tables)",
    )
    parser.add_argument(
        "--known-discrepancy",
        choices=tabled,
        help="a diagnosis: this location's catalogue gives its true F(a) as a table",
    )
    parser.add_argument("--worst", type=int, default=0, help="print each location's N worst tails")
    parser.add_argument(
        "--oracle",
        action="store_true",
        help="score each location's oracle too (benchmarks/location_oracle.py; ~1 min a location)",
    )
    args = parser.parse_args()
    stamp = source_stamp()
    print(f"source {stamp[:12]} (app/ and model/)")
    configure_threads()
    settings_horizon = Settings().forecast_horizon_days
    places = [
        hidden.with_table(p, Settings(), in_catalogue=not args.table_as_constant)
        if p.name == args.geometry_table
        else p
        for p in PLACES
    ]
    places = [
        hidden.with_known_discrepancy(p, Settings()) if p.name == args.known_discrepancy else p
        for p in places
    ]
    fleet = generate_fleet(
        FleetConfig(
            aircraft_per_mix=args.aircraft_per_mix,
            years=YEARS_RECORDED + math.ceil((settings_horizon + 2) / 365),
            discrepancy=DISCREPANCY_20PCT,
            growth_scatter=0.25,
            seed=args.seed,
        )
    )
    recorded = YEARS_RECORDED * fleet.config.flights_per_year
    with tempfile.TemporaryDirectory() as tmp:
        as_of = (fleet.flown_at[recorded - 1] + pd.Timedelta(days=1)).date()
        horizon_at = pd.Timestamp(as_of, tz="UTC") + pd.Timedelta(days=settings_horizon)
        horizon_end = int(fleet.flown_at.searchsorted(horizon_at))  # flights before it
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
        frame = frame[frame["flown_at"] <= fleet.flown_at[recorded - 1]].reset_index(drop=True)
        with factory() as session:
            started = time.perf_counter()
            ingest.ingest_flights(
                session, frame, source="fleet", create_tails=True, actor=BENCH, settings=settings
            )
            upload = time.perf_counter() - started
        print(
            f"upload {len(frame):,} flights ({fleet.size} tails x {recorded}), "
            f"stored once for {len(places)} locations: {upload:.1f} s"
        )
        truths, criticals, measured, count = {}, {}, {}, 0
        for place in places:
            with factory() as session:
                if place.entry:
                    locations.put_location(
                        session, place.name, place.entry, actor=BENCH, settings=settings
                    )
            truths[place.name] = hidden.truth(fleet, place, settings)
            criticals[place.name] = hidden.base_law(place, settings).critical_crack_m
            found = hidden.inspections(fleet, truths[place.name], place, criticals[place.name])
            measured[place.name] = found
            count += len(found)
            with factory() as session:
                ingest.ingest_inspections(
                    session, found, source=place.name, actor=BENCH, settings=settings
                )
        print(f"{count:,} inspections, two rounds per location")
        for place in places:
            if "geometry_table" in place.entry:
                print(f"{place.name}'s geometry table: {place.entry['geometry_table']}")
        print(f"numba's cache warmed (model.runtime.warm_up): {_compile_ahead(env):.1f} CPU s")
        reference = _reference_fit(fleet, settings)
        print(f"reference: one plain fit of the far-field cracks, {reference:.1f} s")
        for workers in args.workers:
            _same_source(stamp)
            seconds, cpu = _retrain_with(workers, settings, factory, env)
            print(
                f"retrain of {len(places)} locations with {workers} worker(s): {seconds:.1f} s "
                f"= {seconds / reference:.1f} x the reference ({cpu:.1f} CPU s, load average "
                f"{os.getloadavg()[0]:.1f})"
            )
        _same_source(stamp)  # the last workers started with the code of the first
        _fitted(factory)
        fpy = fleet.config.flights_per_year
        frames, scores = {}, {}
        for place in places:
            name = place.name
            frames[name] = _service_rows(
                factory, fleet, truths[name], settings, criticals[name], name, recorded, horizon_end
            )
            scores[name] = _scores(frames[name])
            if args.oracle:
                after = {hidden.inspection_id(name, y): y * fpy for y in YEARS_INSPECTED}
                scores[f"{name} (oracle)"] = _scores(
                    oracle_rows(
                        fleet,
                        place,
                        settings,
                        truths[name],
                        measured[name],
                        after,
                        recorded,
                        horizon_end,
                    )
                )
        _print_scores(scores, f"{settings_horizon} days past {as_of}")
        for place in places if args.worst else ():
            print_worst(
                place.name,
                frames[place.name],
                truths[place.name],
                hidden.growth_draws(place, fleet.size),
                criticals[place.name],
                measured[place.name],
                (*(year * fpy for year in YEARS_INSPECTED), recorded),
                args.worst,
            )


if __name__ == "__main__":
    main()
