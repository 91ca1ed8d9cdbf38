"""Background jobs: status, progress, outcome, cancellation."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query
from sqlalchemy.orm import Session

from app.deps import SessionDep, Writer
from app.responses import UNKNOWN_JOB, errors
from app.schemas import JobOut
from app.services import audit, jobs
from app.tables import Job

router = APIRouter(prefix="/jobs", tags=["jobs"])


def _out(job: Job, requested_by: dict[int, str]) -> JobOut:
    result = job.result or {}
    return JobOut(
        job_id=job.id,
        kind=job.kind,
        status=job.status,  # type: ignore[arg-type]
        progress=job.progress,
        stage=job.stage,
        params=job.params,
        model_version=result.get("model_version"),
        outcome=result.get("outcome"),
        outcome_reason=result.get("reason"),
        metrics=result.get("metrics"),
        result=job.result,
        error=job.error,
        created_at=job.created_at,
        started_at=job.started_at,
        finished_at=job.finished_at,
        requested_by=requested_by.get(job.audit_id or -1),
    )


def _one(session: Session, job: Job) -> JobOut:
    return _out(job, audit.actors(session, [job.audit_id]))


@router.get("")
def list_jobs(session: SessionDep, limit: Annotated[int, Query(ge=1, le=500)] = 50) -> list[JobOut]:
    """The most recent jobs first."""
    recent = jobs.list_jobs(session, limit=limit)
    requested_by = audit.actors(session, [job.audit_id for job in recent])
    return [_out(job, requested_by) for job in recent]


@router.get("/{job_id}", responses=errors(UNKNOWN_JOB))
def get_job(job_id: str, session: SessionDep) -> JobOut:
    """A job's status (queued, running, succeeded, failed, cancelled), progress and outcome."""
    return _one(session, jobs.get_job(session, job_id))


@router.post(
    "/{job_id}/cancel", responses=errors(UNKNOWN_JOB, (409, "The job has already finished."))
)
def cancel_job(job_id: str, session: SessionDep, actor: Writer) -> JobOut:
    """Cancel a queued job, or ask a running one to stop at its next progress report."""
    return _one(session, jobs.cancel(session, job_id, actor=actor))
