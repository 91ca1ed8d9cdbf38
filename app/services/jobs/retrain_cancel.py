"""Cancelling a retrain: its jobs per location (app.services.jobs.retrain.enqueue_retrains) share a
`retrain_group` param, so a cancel of any of them cancels every one not finished yet; the
sibling location jobs no longer run on and make candidates of a retrain that was called off."""

from __future__ import annotations

from contextlib import suppress

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.errors import ConflictError
from app.services import audit
from app.services.jobs import queue as jobs
from app.services.jobs.retrain import RETRAIN_GROUP
from app.tables import Job


def cancel_retrain(session: Session, job_id: str, *, actor: audit.Actor) -> Job:
    """Cancel the job (app.services.jobs.queue.cancel) and, where it is one of a retrain's jobs per
    location, every one of them not finished yet: a retrain cancelled stops at every
    location, not only at the one whose id was at hand.  Returns the job asked for."""
    job = jobs.cancel(session, job_id, actor=actor)
    group = (job.params or {}).get(RETRAIN_GROUP) if job.kind == "retrain" else None
    if group is None:
        return job
    unfinished = select(Job).where(
        Job.kind == "retrain", Job.status.in_(("queued", "running")), Job.id != job_id
    )
    for sibling in session.scalars(unfinished).all():
        if (sibling.params or {}).get(RETRAIN_GROUP) == group:
            with suppress(ConflictError):  # it finished meanwhile
                jobs.cancel(session, sibling.id, actor=actor)
    session.refresh(job)
    return job
