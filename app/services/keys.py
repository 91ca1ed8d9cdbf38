"""API keys: create (the key is shown once), list, revoke, and find the key a request presents.

A key reads `fpk_<key_id>_<secret>`: key_id (8 hex digits) is public and finds the row; the
secret (32 random bytes, URL-safe base64) is stored only as SHA-256(salt + secret).  A random
256-bit secret cannot be guessed, so it needs no slow password hash; the per-key salt keeps two
stored hashes of one secret apart.  Roles are ordered: read < write < admin (app.tables.ROLES).
"""

from __future__ import annotations

import hashlib
import hmac
import re
import secrets
from dataclasses import dataclass
from datetime import UTC, datetime

from sqlalchemy import ColumnElement, select, update
from sqlalchemy.orm import Session

from app.errors import ConflictError, NotFoundError
from app.services import audit
from app.tables import ROLES, ApiKey

PREFIX = "fpk"
_KEY = re.compile(rf"^{PREFIX}_([0-9a-f]{{8}})_([A-Za-z0-9_-]{{43}})$")
# No ":" in a key's name: "cli:<command>" names a local command in the audit log.
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._@-]{0,63}$")


@dataclass(frozen=True)
class NewKey:
    """A created key: `key` is the only copy of the secret."""

    key: str
    key_id: str
    name: str
    role: str


def allows(role: str, needed: str) -> bool:
    """Whether `role` may do what `needed` may (admin ⊇ write ⊇ read)."""
    return ROLES.index(role) >= ROLES.index(needed)


def _digest(salt: str, secret: str) -> str:
    return hashlib.sha256(bytes.fromhex(salt) + secret.encode()).hexdigest()


def _live(name: str) -> ColumnElement[bool]:
    return (ApiKey.name == name) & ApiKey.revoked_at.is_(None)


def create_key(session: Session, *, role: str, name: str, replace: bool = False) -> NewKey:
    """Store a new key of `role` named `name` and return it (the secret is not kept).

    replace: revoke a live key of the same name first; otherwise a live key of that name is a
    ConflictError.  Raises ValueError for an unknown role or a name that is not 1-64 letters,
    digits or . _ @ - (starting with a letter or digit).
    """
    if role not in ROLES:
        raise ValueError(f"role must be one of {ROLES}, got {role!r}")
    if not _NAME.match(name):
        raise ValueError(
            f"name must be 1-64 letters, digits or . _ @ - starting with a letter or digit, "
            f"got {name!r}"
        )
    actor = audit.local("keys")
    if replace:
        for old in session.scalars(select(ApiKey).where(_live(name))):
            _revoke(session, old, actor)
    elif session.scalar(select(ApiKey.id).where(_live(name))) is not None:
        raise ConflictError(f"a live key is named {name!r}: revoke it or pass --replace")
    while True:  # 2**32 key ids: a collision is rare, and simply drawn again
        key_id = secrets.token_hex(4)
        if session.scalar(select(ApiKey.id).where(ApiKey.key_id == key_id)) is None:
            break
    secret = secrets.token_urlsafe(32)
    salt = secrets.token_hex(16)
    session.add(
        ApiKey(key_id=key_id, name=name, role=role, salt=salt, key_hash=_digest(salt, secret))
    )
    audit.record(session, actor, "key.create", f"key/{key_id}", {"name": name, "role": role})
    session.commit()
    return NewKey(f"{PREFIX}_{key_id}_{secret}", key_id, name, role)


def list_keys(session: Session) -> list[ApiKey]:
    """Every key, live and revoked, oldest first."""
    return list(session.scalars(select(ApiKey).order_by(ApiKey.id)))


def _revoke(session: Session, key: ApiKey, actor: audit.Actor) -> None:
    session.execute(update(ApiKey).where(ApiKey.id == key.id).values(revoked_at=datetime.now(UTC)))
    audit.record(
        session, actor, "key.revoke", f"key/{key.key_id}", {"name": key.name, "role": key.role}
    )


def revoke_key(session: Session, ident: str) -> ApiKey:
    """Revoke the live key with this key_id or name; raises NotFoundError."""
    key = session.scalars(
        select(ApiKey).where(
            ApiKey.revoked_at.is_(None), (ApiKey.key_id == ident) | (ApiKey.name == ident)
        )
    ).first()
    if key is None:
        raise NotFoundError(f"no live key has the id or name {ident!r}")
    _revoke(session, key, audit.local("keys"))
    session.commit()
    session.refresh(key)
    return key


def find_key(session: Session, presented: str) -> ApiKey | None:
    """The live key whose secret this is; None for a malformed, unknown, wrong or revoked key."""
    match = _KEY.match(presented.strip())
    if match is None:
        return None
    key_id, secret = match.groups()
    key = session.scalars(select(ApiKey).where(ApiKey.key_id == key_id)).one_or_none()
    if key is None or key.revoked_at is not None:
        return None
    return key if hmac.compare_digest(key.key_hash, _digest(key.salt, secret)) else None
