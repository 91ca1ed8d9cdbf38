"""Background jobs: status, progress, outcome, cancellation."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query
from sqlalchemy.orm import Session

from app.deps import SessionDep, Writer
from app.responses import UNKNOWN_JOB, errors
from app.schemas import JobOut
from app.services.jobs import queue as jobs
from app.services.jobs import retrain_cancel
from app.services.records import stored

router = APIRouter(prefix="/jobs", tags=["jobs"])


def _one(session: Session, job: stored.Job) -> JobOut:
    return JobOut.model_validate(stored.jobs(session, [job])[0])


@router.get("")
def list_jobs(session: SessionDep, limit: Annotated[int, Query(ge=1, le=500)] = 50) -> list[JobOut]:
    """The most recent jobs first."""
    recent = jobs.list_jobs(session, limit=limit)
    return [JobOut.model_validate(job) for job in stored.jobs(session, recent)]


@router.get("/{job_id}", responses=errors(UNKNOWN_JOB))
def get_job(job_id: str, session: SessionDep) -> JobOut:
    """A job's status (queued, running, succeeded, failed, cancelled), progress and outcome."""
    return _one(session, jobs.get_job(session, job_id))


@router.post(
    "/{job_id}/cancel", responses=errors(UNKNOWN_JOB, (409, "The job has already finished."))
)
def cancel_job(job_id: str, session: SessionDep, actor: Writer) -> JobOut:
    """Cancel a queued job, or ask a running one to stop at its next progress report; a
    retrain's job cancels the retrain's jobs at every location."""
    return _one(session, retrain_cancel.cancel_retrain(session, job_id, actor=actor))
