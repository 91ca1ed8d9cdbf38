"""The jobs table as a queue: enqueue, claim, report progress, finish, cancel.

Claiming is "pick the oldest claimable job, then flip it to running only if still claimable":
the guarded UPDATE makes two claimers safe on SQLite, and on PostgreSQL the same SELECT already
carries FOR UPDATE SKIP LOCKED, so concurrent workers skip each other's rows instead of waiting.
A running job's worker beats (heartbeat_at) while it runs; a job whose heartbeat is older than
the stale limit lost its worker and is claimed again.
"""

from __future__ import annotations

import uuid
from datetime import UTC, datetime, timedelta
from typing import Any

from sqlalchemy import ColumnElement, and_, or_, select, update
from sqlalchemy.orm import Session

from app.errors import ConflictError, NotFoundError
from app.services import audit
from app.tables import Job

JOB_KINDS = ("retrain", "forecast-batch")
FINISHED = ("succeeded", "failed", "cancelled")
MAX_ATTEMPTS = 3


def enqueue(session: Session, kind: str, params: dict[str, Any], *, actor: audit.Actor) -> Job:
    """Queue a job of `kind` for `actor` (recorded in the audit log)."""
    if kind not in JOB_KINDS:
        raise ValueError(f"kind must be one of {JOB_KINDS}, got {kind!r}")
    job_id = uuid.uuid4().hex
    event = audit.record(session, actor, kind, f"job/{job_id}", {"params": params})
    job = Job(id=job_id, kind=kind, status="queued", progress=0.0, params=params, audit_id=event)
    session.add(job)
    session.commit()
    return job


def requested_by(session: Session, job: Job) -> audit.Actor | None:
    """Who queued the job (None for jobs queued before the audit log)."""
    return None if job.audit_id is None else audit.actor_of(session, job.audit_id)


def get_job(session: Session, job_id: str) -> Job:
    job = session.get(Job, job_id)
    if job is None:
        raise NotFoundError(f"unknown job {job_id!r}")
    return job


def list_jobs(session: Session, *, limit: int) -> list[Job]:
    return list(session.scalars(select(Job).order_by(Job.created_at.desc()).limit(limit)))


def _claimable(stale_before: datetime) -> ColumnElement[bool]:
    # Queued, or running under a worker whose heartbeat stopped (its process died).
    return or_(
        Job.status == "queued",
        and_(Job.status == "running", Job.heartbeat_at < stale_before),
    )


def claim_next(session: Session, worker: str, *, stale_after_s: float = 300.0) -> str | None:
    """Mark the oldest claimable job running for `worker` and return its id (None: none left).

    A job abandoned MAX_ATTEMPTS times (its worker died each time) is failed instead of run again.
    """
    now = datetime.now(UTC)
    stale_before = now - timedelta(seconds=stale_after_s)
    while True:
        candidate = session.execute(
            select(Job.id, Job.attempts)
            .where(_claimable(stale_before))
            .order_by(Job.created_at)
            .limit(1)
            .with_for_update(skip_locked=True)
        ).first()
        if candidate is None:
            session.rollback()
            return None
        job_id, attempts = candidate
        guard = and_(Job.id == job_id, _claimable(stale_before))
        if attempts >= MAX_ATTEMPTS:
            session.execute(
                update(Job)
                .where(guard)
                .values(
                    status="failed",
                    finished_at=now,
                    error=f"abandoned: its worker stopped during {attempts} attempts",
                )
            )
            session.commit()
            continue
        claimed = session.execute(
            update(Job)
            .where(guard)
            .values(
                status="running",
                started_at=now,
                heartbeat_at=now,
                worker=worker,
                attempts=Job.attempts + 1,
            )
        )
        session.commit()
        if claimed.rowcount == 1:  # type: ignore[attr-defined]
            return job_id
        # another worker claimed it first (SQLite has no SKIP LOCKED: both read the same
        # oldest job): the next one may be free, so a retrain's jobs per location run in
        # parallel and a `worker --once` that lost a race does not stop early


def heartbeat(session: Session, job_id: str) -> None:
    """The running job's worker is alive."""
    session.execute(
        update(Job)
        .where(Job.id == job_id, Job.status == "running")
        .values(heartbeat_at=datetime.now(UTC))
    )
    session.commit()


def report_progress(
    session: Session, job_id: str, progress: float, stage: str | None = None
) -> bool:
    """Store progress (0..1) and, where given, the stage; also a heartbeat.  True when asked to
    cancel the job."""
    values: dict[str, Any] = {
        "progress": min(max(progress, 0.0), 1.0),
        "heartbeat_at": datetime.now(UTC),
    }
    if stage is not None:
        values["stage"] = stage[:64]
    session.execute(update(Job).where(Job.id == job_id).values(**values))
    session.commit()
    return bool(session.scalar(select(Job.cancel_requested).where(Job.id == job_id)))


def finish(
    session: Session,
    job_id: str,
    status: str,
    *,
    result: dict[str, Any] | None = None,
    error: str | None = None,
) -> None:
    if status not in FINISHED:
        raise ValueError(f"status must be one of {FINISHED}, got {status!r}")
    values: dict[str, Any] = {"status": status, "finished_at": datetime.now(UTC), "error": error}
    if status == "succeeded":
        values.update(progress=1.0, result=result, stage="done")
    session.execute(update(Job).where(Job.id == job_id).values(**values))
    session.commit()


def cancel(session: Session, job_id: str, *, actor: audit.Actor) -> Job:
    """Cancel a queued job at once; ask a running one to stop at its next progress report."""
    job = get_job(session, job_id)
    if job.status in FINISHED:
        raise ConflictError(f"job {job_id} already {job.status}")
    audit.record(session, actor, "job.cancel", f"job/{job_id}", {"status": job.status})
    session.execute(
        update(Job)
        .where(Job.id == job_id, Job.status == "queued")
        .values(status="cancelled", finished_at=datetime.now(UTC))
    )
    session.execute(update(Job).where(Job.id == job_id).values(cancel_requested=True))
    session.commit()
    session.refresh(job)
    return job
