"""Model versions: retrain (a job), list, inspect, activate (rollback)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Response, status
from sqlalchemy.orm import Session

from app.deps import Admin, SessionDep, Writer
from app.responses import QUEUE_FULL, UNKNOWN_VERSION, errors
from app.schemas import JobAccepted, ModelVersionOut, RetrainIn, VersionPath
from app.services import models as model_service
from app.services.jobs import queue as jobs
from app.services.jobs import retrain as retrain_service
from app.services.records import stored

router = APIRouter(prefix="/models", tags=["models"])


def _out(session: Session, row: stored.Version) -> ModelVersionOut:
    return ModelVersionOut.model_validate(stored.versions(session, [row])[0])


@router.post("/retrain", status_code=status.HTTP_202_ACCEPTED, responses=errors(QUEUE_FULL))
def retrain(
    session: SessionDep, actor: Writer, body: Annotated[RetrainIn | None, Body()] = None
) -> JobAccepted:
    """Queue a retrain on every inspected aircraft, one job per location with inspections
    (job_id: the default location's; jobs: each location's); poll GET /jobs/{job_id}.  A
    location whose retrain is still queued gets that job back (already_queued).  Each new
    version becomes active only if it passes its location's promotion gate."""
    params = (body or RetrainIn()).model_dump(exclude_none=True)
    default_job, queued = retrain_service.enqueue_retrains(session, params, actor=actor)
    already = jobs.already_queued(session)
    return JobAccepted(job_id=default_job, status="queued", jobs=queued, already_queued=already)


@router.get("")
def list_models(session: SessionDep) -> list[ModelVersionOut]:
    """Every stored model version, oldest first."""
    listed = stored.versions(session, model_service.list_versions(session))
    return [ModelVersionOut.model_validate(v) for v in listed]


@router.get("/{version:int}", responses=errors(UNKNOWN_VERSION))
def get_model(version: VersionPath, session: SessionDep) -> ModelVersionOut:
    """One model version with its training summary and validation metrics."""
    return _out(session, model_service.get_version(session, version))


@router.get(
    "/{version:int}/file",
    response_class=Response,
    responses={200: {"content": {"application/octet-stream": {}}}, **errors(UNKNOWN_VERSION)},
)
def download_model(version: VersionPath, session: SessionDep) -> Response:
    """The version's model file, for offline use: `fleetpinn predict --model FILE`."""
    return Response(
        model_service.model_file(session, version),
        media_type="application/octet-stream",
        headers={"Content-Disposition": f'attachment; filename="fleetpinn-model-v{version}.pt"'},
    )


@router.post("/{version:int}/activate", responses=errors(UNKNOWN_VERSION))
def activate_model(version: VersionPath, session: SessionDep, actor: Admin) -> ModelVersionOut:
    """Serve forecasts from this version, whatever its gate said (rollback, or an admin's
    promotion of a refused candidate); audited."""
    return _out(session, model_service.activate(session, version, actor=actor))
