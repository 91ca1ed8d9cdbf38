"""`fleetpinn client retrain | jobs`: jobs of a running service, followed on a progress bar.

A retrain that the promotion gate refused finished as a job ("succeeded") but did not replace
the active model: every output says "refused" and why (the gate's verdict stored with the job,
and the inspections it blames where the verdict lists them as `culprits`), never only
"succeeded, version 2".
"""

from __future__ import annotations

import argparse
import time
from typing import Any

from app.cli import output as out
from app.cli.api import Api
from app.cli.progress import Bar
from app.cli.registry import CommandFailed
from app.web import format as fmt

FINISHED = ("succeeded", "failed", "cancelled")
_POLL_S = 0.5

_JOB_COLUMNS = [
    out.Column("job_id", "job"),
    out.Column("kind", "kind"),
    out.Column("status", "status"),
    out.Column("outcome", "outcome", out.text),
    out.Column("progress", "progress", out.percent, numeric=True),
    out.Column("stage", "stage", out.text),
    out.Column("model_version", "version", out.text, numeric=True),
    out.Column("finished_at", "finished (UTC)", out.stamp),
    out.Column("error", "error", out.text),
]


def _gate(job: dict[str, Any]) -> dict[str, Any]:
    """The promotion gate's verdict stored with a retrain job ({} where there is none)."""
    return dict((job.get("metrics") or {}).get("gate") or {})


def _outcome(job: dict[str, Any]) -> str | None:
    """A retrain's end in words: a refused one says so and why, never just "succeeded"."""
    outcome = job.get("outcome")
    if outcome == "refused":
        reason = _gate(job).get("reason") or job.get("outcome_reason")
        return f"refused by the promotion gate: {reason}" if reason else "refused"
    return outcome


def _job_rows(listed: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{**job, "outcome": _outcome(job)} for job in listed]


def _verdict_lines(job: dict[str, Any]) -> list[str]:
    """A refused retrain's verdict for people: what was kept, why, and the inspections the gate
    blames (the verdict's `culprits` and the flagged inspections it trained on, where it lists
    them)."""
    if job.get("outcome") != "refused":
        return []
    active = _gate(job).get("active_version")
    kept = f"v{active} stays active" if active else "no version was activated"
    version = job.get("model_version")
    stored = (
        "no version is stored" if version is None else f"model v{version} is stored as a candidate"
    )
    lines = [f"retrain REFUSED: {stored} and {kept}; {_outcome(job)}"]
    culprits = _gate(job).get("culprits") or []
    if culprits:
        lines.append(f"inspections that drove the refusal ({len(culprits)}):")
        lines += [f"  {fmt.culprit(c)}" for c in culprits]
    flagged = _gate(job).get("flagged") or []
    if flagged:
        lines.append(f"flagged inspections it trained on ({len(flagged)}):")
        lines += [f"  {fmt.culprit(f)}" for f in flagged]
    return lines


def wait_for(api: Api, job_id: str, title: str) -> dict[str, Any]:
    """Poll the job until it ends, its progress and stage on a bar; returns its last record."""
    with Bar(title) as bar:
        while True:
            job: dict[str, Any] = api.json("GET", f"/jobs/{job_id}")
            bar.update(job["progress"], job["stage"] or job["status"])
            if job["status"] in FINISHED:
                return job
            time.sleep(_POLL_S)


def retrain(api: Api, args: argparse.Namespace) -> int:
    params = {
        "kernel": args.kernel,
        "lbfgs_iterations": args.lbfgs_iterations,
        "seed": args.seed,
        "activate": False if args.no_activate else None,
    }
    body = {k: v for k, v in params.items() if v is not None}
    accepted = api.json("POST", "/models/retrain", json=body)
    # one job per location: --wait follows each and reports every one
    queued: dict[str, str] = accepted.get("jobs") or {"default": accepted["job_id"]}
    several = len(queued) > 1
    if args.wait:
        done = {
            name: wait_for(api, job_id, f"retrain {name}" if several else "retrain")
            for name, job_id in queued.items()
        }
    else:
        done = {name: {"job_id": job_id, "status": "queued"} for name, job_id in queued.items()}
    mode = out.mode_of(args)
    columns = _JOB_COLUMNS if args.wait else _JOB_COLUMNS[:3]
    if several:
        columns = [out.Column("location", "location"), *columns]
    rows = [{**job, "location": name} for name, job in done.items()]
    document: Any = rows if several else next(iter(done.values()))
    if not args.wait:
        document = accepted
    out.emit(mode, document, _job_rows(rows), columns)
    if mode == "table":
        for name, job in done.items():
            lines = _verdict_lines(job)
            if lines and several:
                print(f"location {name}:")
            for line in lines:
                print(line)
    failed = [(name, job) for name, job in done.items() if job["status"] != "succeeded"]
    if args.wait and failed:
        said = "; ".join(
            (f"location {name}: " if several else "")
            + f"job {job['job_id']} {job['status']}: {job.get('error')}"
            for name, job in failed
        )
        raise CommandFailed(said)
    return 0


def jobs(api: Api, args: argparse.Namespace) -> int:
    mode = out.mode_of(args)
    if args.job_id:
        job = api.json("GET", f"/jobs/{args.job_id}")
        out.emit(mode, job, _job_rows([job]), _JOB_COLUMNS)
        if mode == "table":
            for line in _verdict_lines(job):
                print(line)
        return 0
    listed = api.json("GET", "/jobs", params={"limit": args.limit})
    out.emit(mode, listed, _job_rows(listed), _JOB_COLUMNS, title="jobs, newest first")
    return 0
