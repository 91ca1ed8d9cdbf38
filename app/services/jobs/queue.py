"""The jobs table as a queue: enqueue, claim, report progress, finish, cancel.

Claiming is "pick the oldest claimable job, then flip it to running only if still claimable":
the guarded UPDATE makes two claimers safe on SQLite, and on PostgreSQL the same SELECT already
carries FOR UPDATE SKIP LOCKED, so concurrent workers skip each other's rows instead of waiting.
A running job's worker beats (heartbeat_at) while it runs; a job whose heartbeat is older than
the stale limit lost its worker and is claimed again.

Admission (enqueue, under a lock on the queue): at most one queued retrain per location, a
request for another getting the queued one back (already_queued() names it), and at most
max_queued_jobs queued jobs in all where the session carries the limit (the API's sessions do:
QUEUE_LIMIT in Session.info), QueueFull (HTTP 429) past it.  Fifty concurrent retrains once
queued 50 jobs, about 100 h of worker time (issue 42).
"""

from __future__ import annotations

import uuid
from datetime import UTC, datetime, timedelta
from typing import Any

from sqlalchemy import ColumnElement, and_, func, or_, select, text, update
from sqlalchemy.orm import Session

from app.default_location import DEFAULT_LOCATION
from app.errors import ConflictError, NotFoundError, QueueFull
from app.services import audit
from app.tables import Job

JOB_KINDS = ("retrain", "forecast-batch")
FINISHED = ("succeeded", "failed", "cancelled")
MAX_ATTEMPTS = 3


# Session.info keys: the most queued jobs the session may add to (set on the API's sessions by
# its lifespan), and the queued jobs enqueue handed back instead of adding one.
QUEUE_LIMIT = "fleetpinn_max_queued_jobs"
_ALREADY_QUEUED = "fleetpinn_already_queued"
# PostgreSQL's advisory lock on the queue (any constant the service uses for nothing else)
_QUEUE_LOCK = 0x6A6F6273


def enqueue(session: Session, kind: str, params: dict[str, Any], *, actor: audit.Actor) -> Job:
    """Queue a job of `kind` for `actor` (recorded in the audit log), or return the retrain
    already queued for the same location (its options stand; already_queued() lists it).
    Raises QueueFull when the session's QUEUE_LIMIT of queued jobs is reached."""
    if kind not in JOB_KINDS:
        raise ValueError(f"kind must be one of {JOB_KINDS}, got {kind!r}")
    waiting = _admit(session, kind, params)
    if waiting is not None:
        session.commit()  # ends the transaction that holds the queue's lock
        session.info.setdefault(_ALREADY_QUEUED, []).append(waiting.id)
        return waiting
    job_id = uuid.uuid4().hex
    event = audit.record(session, actor, kind, f"job/{job_id}", {"params": params})
    job = Job(id=job_id, kind=kind, status="queued", progress=0.0, params=params, audit_id=event)
    session.add(job)
    session.commit()
    return job


def already_queued(session: Session) -> list[str]:
    """The ids enqueue returned in this session that an earlier request had queued."""
    return list(session.info.get(_ALREADY_QUEUED, []))


def _admit(session: Session, kind: str, params: dict[str, Any]) -> Job | None:
    """The admission check, in a transaction that holds the queue's lock until the caller
    commits (so two requests cannot both see no queued retrain, or room for one more job):
    the queued retrain of params' location, if any; else None, or QueueFull."""
    _lock_queue(session)
    if kind == "retrain":
        location = params.get("location", DEFAULT_LOCATION)
        queued = session.scalars(
            select(Job)
            .where(Job.kind == "retrain", Job.status == "queued")
            .order_by(Job.created_at)
        )
        for job in queued:
            if (job.params or {}).get("location", DEFAULT_LOCATION) == location:
                return job
    limit = session.info.get(QUEUE_LIMIT)
    if limit is not None:
        count = session.scalar(select(func.count()).select_from(Job).where(Job.status == "queued"))
        if count is not None and count >= limit:
            session.rollback()
            raise QueueFull(
                f"{count} jobs are queued, at most {limit} (FLEETPINN_MAX_QUEUED_JOBS): "
                "nothing was queued; try again when some have run, or cancel one"
            )
    return None


def _lock_queue(session: Session) -> None:
    """Take the queue's write lock for the rest of the transaction: PostgreSQL's advisory lock,
    SQLite's database write lock (an UPDATE that changes nothing takes it, waiting its turn)."""
    if session.get_bind().dialect.name == "postgresql":
        session.execute(text("SELECT pg_advisory_xact_lock(:key)"), {"key": _QUEUE_LOCK})
    else:
        session.execute(text("UPDATE jobs SET status = status WHERE 0"))


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
