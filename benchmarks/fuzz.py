"""schemathesis over every operation with many examples: the hostile-input goals of issues 9 and 19.

    make postgres
    .venv/bin/python -m benchmarks.fuzz [--examples 100] [--backend sqlite|postgresql]
        [--checks all [--exclude-checks positive_data_acceptance,...]]
        [--phases examples,coverage,fuzzing] [--select "forecast or ranking"]
        [--pytest-output /tmp/fuzz.txt]

Runs tests/app/test_fuzz.py (real servers on SQLite and PostgreSQL with a small fleet and an
active model, each under a 4 GiB address-space limit, RLIMIT_AS; every operation with an admin
key and with a read key) with the explicit examples, the coverage phase (boundary and invalid
values of every parameter) and --examples generated requests per operation, instead of the few
of `make test`.  Prints one JSON object: per backend, role and operation the requests sent;
the 5xx answers, the answers slower than the time limit (request_timeout_seconds), the slowest
answer, each server's peak resident memory against the ceiling docs/api.md states, and pytest's
result line (a failure there is a server error, an undocumented status, an answer off its
schema or one over the time limit).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

from app.config import Settings

# The resident memory an API process stays under (docs/api.md, "Limits").
RSS_CEILING_BYTES = 2 * 1024**3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", type=int, default=100)
    parser.add_argument("--backend", choices=("sqlite", "postgresql"), default=None)
    parser.add_argument(
        "--checks",
        choices=("default", "all"),
        default="default",
        help="all: every schemathesis check (positive data accepted, negative rejected, ...)",
    )
    parser.add_argument(
        "--exclude-checks",
        default="",
        help="with --checks all: these checks left out (comma-separated names), so that an "
        "operation's first find of one does not hide the others' (hypothesis stops there)",
    )
    parser.add_argument("--phases", default="examples,coverage,fuzzing")
    parser.add_argument(
        "--select",
        default="",
        help="only the operations whose test id matches this pytest -k expression (e.g. "
        "'forecast or ranking'): a small run of the operations a change touches",
    )
    parser.add_argument(
        "--pytest-output",
        type=Path,
        default=None,
        help="keep pytest's whole output here: each failure's request, answer and curl line "
        "(the JSON names the failed operations only)",
    )
    args = parser.parse_args()
    limit_s = Settings().request_timeout_seconds
    with tempfile.TemporaryDirectory(prefix="fleetpinn-fuzz-") as folder:
        log = Path(folder) / "requests.tsv"
        env = {
            **os.environ,
            "FLEETPINN_FUZZ_EXAMPLES": str(args.examples),
            "FLEETPINN_FUZZ_PHASES": args.phases,
            "FLEETPINN_FUZZ_CHECKS": args.checks,
            "FLEETPINN_FUZZ_EXCLUDE": args.exclude_checks,
            "FLEETPINN_FUZZ_LOG": str(log),
        }
        command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-rf"]
        command += ["tests/app/test_fuzz.py"]
        chosen = " and ".join(f"({k})" for k in (args.backend, args.select) if k)
        if chosen:
            command += ["-k", chosen]
        started = time.perf_counter()
        run = subprocess.run(command, env=env, capture_output=True, text=True)
        seconds = time.perf_counter() - started
        if args.pytest_output:
            args.pytest_output.write_text(run.stdout + run.stderr)
        lines = log.read_text().splitlines() if log.exists() else []
        rss_path = Path(f"{log}.rss")
        rss = (
            [line.split("\t") for line in rss_path.read_text().splitlines()]
            if rss_path.exists()
            else []
        )
    rows = [line.split("\t") for line in lines]
    requests = Counter(f"{backend} {role} {operation}" for backend, role, operation, *_ in rows)
    durations = [float(row[4]) for row in rows]
    failed = [line for line in run.stdout.splitlines() if line.startswith("FAILED")]
    peak = {backend: int(value) for backend, value in rss}
    result = run.stdout.strip().splitlines()[-1] if run.stdout.strip() else run.stderr[-500:]
    print(
        json.dumps(
            {
                "examples_per_operation": args.examples,
                "operations_x_backends_x_roles": len(requests),
                "requests": sum(requests.values()),
                "fewest_requests_per_operation": min(requests.values(), default=0),
                "server_errors": sum(1 for row in rows if row[3].startswith("5")),
                "failed_checks": len(failed),
                "time_limit_s": limit_s,
                "over_time_limit": sum(1 for d in durations if d > limit_s),
                "slowest_s": round(max(durations, default=0.0), 2),
                "peak_rss_mb": {b: round(v / 2**20) for b, v in peak.items()},
                "rss_ceiling_mb": RSS_CEILING_BYTES // 2**20,
                "under_rss_ceiling": all(v < RSS_CEILING_BYTES for v in peak.values()),
                "pytest": result,
                "failures": failed[:20],
                "seconds": round(seconds, 1),
                "requests_per_operation": dict(sorted(requests.items())),
            }
        )
    )
    sys.exit(run.returncode)


if __name__ == "__main__":
    main()
