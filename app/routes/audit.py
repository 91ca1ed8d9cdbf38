"""The audit log: who wrote what, when, and what it replaced (admin keys only)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query

from app.deps import Admin, SessionDep
from app.schemas_ops import AuditEventOut, AuditPage
from app.services import audit

router = APIRouter(prefix="/audit", tags=["audit"])


@router.get("", responses={403: {"description": "Needs an admin key."}})
def list_audit_events(
    session: SessionDep,
    _: Admin,
    limit: Annotated[int, Query(ge=1, le=1000)] = 50,
    offset: Annotated[int, Query(ge=0, le=2**31 - 1)] = 0,
    subject: Annotated[str | None, Query(max_length=300, description="e.g. N100/I1")] = None,
    action: Annotated[
        str | None, Query(max_length=32, description="e.g. inspection.correct")
    ] = None,
) -> AuditPage:
    """Audit events, newest first, optionally of one subject or action."""
    events, total = audit.list_events(
        session, limit=limit, offset=offset, subject=subject, action=action
    )
    return AuditPage(
        items=[
            AuditEventOut(
                id=e.id,
                at=e.at,
                actor=e.actor,
                role=e.role,
                action=e.action,
                subject=e.subject,
                request_id=e.request_id,
                detail=e.detail,
            )
            for e in events
        ],
        total=total,
        limit=limit,
        offset=offset,
    )
