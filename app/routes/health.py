"""Liveness and readiness."""

from __future__ import annotations

from fastapi import APIRouter, Response, status
from sqlalchemy.exc import SQLAlchemyError

from app.default_location import DEFAULT_LOCATION
from app.deps import SessionDep
from app.schemas import HealthOut, ReadyOut
from app.services import models as model_service

router = APIRouter(tags=["health"])


@router.get("/health")
def health() -> HealthOut:
    """The process is up."""
    return HealthOut()


@router.get("/ready", responses={503: {"model": ReadyOut}})
def ready(session: SessionDep, response: Response) -> ReadyOut:
    """The database answers; says which model versions (if any) serve forecasts."""
    try:
        versions = model_service.active_versions_by_name(session)
    except SQLAlchemyError:
        response.status_code = status.HTTP_503_SERVICE_UNAVAILABLE
        return ReadyOut(status="unavailable", database=False, model_version=None)
    return ReadyOut(
        status="ready",
        database=True,
        model_version=versions.get(DEFAULT_LOCATION),
        model_versions=versions,
    )
