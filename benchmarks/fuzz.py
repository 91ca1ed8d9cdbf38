"""schemathesis over every operation with many examples: the hostile-input goal of issue 9.

    make postgres
    .venv/bin/python -m benchmarks.fuzz [--examples 100]

Runs tests/app/test_fuzz.py (real servers on SQLite and PostgreSQL with a small fleet and an
active model) with the explicit examples, the coverage phase (boundary and invalid values of
every parameter) and --examples generated requests per operation, instead of the few of
`make test`.  Prints one JSON object: per backend and operation the requests sent and the 5xx
answers, and pytest's result line (a failure there is a server error, an undocumented status or
an answer that does not match its schema).
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", type=int, default=100)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="fleetpinn-fuzz-") as folder:
        log = Path(folder) / "requests.tsv"
        env = {
            **os.environ,
            "FLEETPINN_FUZZ_EXAMPLES": str(args.examples),
            "FLEETPINN_FUZZ_PHASES": "examples,coverage,fuzzing",
            "FLEETPINN_FUZZ_LOG": str(log),
        }
        started = time.perf_counter()
        run = subprocess.run(
            [
                sys.executable,
                "-m",
                "pytest",
                "-q",
                "-p",
                "no:cacheprovider",
                "tests/app/test_fuzz.py",
            ],
            env=env,
            capture_output=True,
            text=True,
        )
        seconds = time.perf_counter() - started
        lines = log.read_text().splitlines() if log.exists() else []
    rows = [line.split("\t") for line in lines]
    requests = Counter(f"{backend} {operation}" for backend, operation, _ in rows)
    server_errors = sum(1 for *_, status in rows if status.startswith("5"))
    result = run.stdout.strip().splitlines()[-1] if run.stdout.strip() else run.stderr[-500:]
    print(
        json.dumps(
            {
                "examples_per_operation": args.examples,
                "operations_x_backends": len(requests),
                "requests": sum(requests.values()),
                "fewest_requests_per_operation": min(requests.values(), default=0),
                "server_errors": server_errors,
                "pytest": result,
                "seconds": round(seconds, 1),
                "requests_per_operation": dict(sorted(requests.items())),
            }
        )
    )
    sys.exit(run.returncode)


if __name__ == "__main__":
    main()
