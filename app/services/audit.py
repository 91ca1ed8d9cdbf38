"""The audit log: every write records who made it (an API key, or a local command), when, what
it touched and what it replaced (table audit_events).

Writers call record() inside their own transaction, so an event exists exactly when its write
was committed; the rows a write stores point at its event (audit_id).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.in_lists import chunks
from app.tables import AuditEvent


@dataclass(frozen=True)
class Actor:
    """Who writes: the API key's name and role (api_key_id None for a local command run by
    someone with the database's credentials), and the id of the HTTP request, if any."""

    name: str
    role: str
    api_key_id: int | None = None
    request_id: str | None = None


def local(command: str) -> Actor:
    """A local command (`fleetpinn seed-demo`, `keys create`): whoever holds the database."""
    return Actor(name=f"cli:{command}", role="admin")


def record(
    session: Session, actor: Actor, action: str, subject: str, detail: dict[str, Any]
) -> int:
    """Add an event to the caller's transaction (the caller commits) and return its id."""
    event = AuditEvent(
        at=datetime.now(UTC),
        api_key_id=actor.api_key_id,
        actor=actor.name,
        role=actor.role,
        action=action,
        subject=subject[:300],
        request_id=actor.request_id,
        detail=detail,
    )
    session.add(event)
    session.flush()
    return event.id


def actor_of(session: Session, audit_id: int) -> Actor | None:
    """The actor of one event (None for an unknown id)."""
    event = session.get(AuditEvent, audit_id)
    if event is None:
        return None
    return Actor(event.actor, event.role, event.api_key_id, event.request_id)


def list_events(
    session: Session,
    *,
    limit: int,
    offset: int = 0,
    subject: str | None = None,
    action: str | None = None,
) -> tuple[list[AuditEvent], int]:
    """The newest events first (optionally of one subject or action), and how many match."""
    query = select(AuditEvent)
    if subject is not None:
        query = query.where(AuditEvent.subject == subject)
    if action is not None:
        query = query.where(AuditEvent.action == action)
    total = session.scalar(select(func.count()).select_from(query.subquery())) or 0
    page = query.order_by(AuditEvent.id.desc()).limit(limit).offset(offset)
    return list(session.scalars(page)), total


def actors(session: Session, audit_ids: Sequence[int | None]) -> dict[int, str]:
    """The actor of each of these events, by event id (unknown ids left out)."""
    wanted = sorted({i for i in audit_ids if i is not None})
    found: dict[int, str] = {}
    for part in chunks(wanted):
        rows = session.execute(
            select(AuditEvent.id, AuditEvent.actor).where(AuditEvent.id.in_(part))
        )
        found.update({ident: actor for ident, actor in rows})
    return found
