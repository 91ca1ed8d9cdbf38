"""Prometheus scrape endpoint (open, like the health checks: it holds counts and latencies, no
fleet data)."""

from __future__ import annotations

from fastapi import APIRouter, Response

from app import metrics
from app.deps import SessionDep
from app.services import models as model_service
from app.services.records import stored

router = APIRouter(tags=["health"])


@router.get(
    "/metrics",
    response_class=Response,
    responses={200: {"content": {metrics.CONTENT_TYPE: {}}, "description": "Text format."}},
)
def scrape(session: SessionDep) -> Response:
    """This process's request, ingest and job metrics, and the active model version."""
    body = metrics.exposition(
        model_service.active_version_number(session), stored.job_counts(session)
    )
    return Response(body, media_type=metrics.CONTENT_TYPE)
