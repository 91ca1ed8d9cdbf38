"""Model versions: store, list, activate (rollback), and load the weights for serving."""

from __future__ import annotations

import threading
from collections import OrderedDict
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, defer

from app.errors import ConflictError, NotFoundError
from app.services import audit
from app.tables import DEFAULT_LOCATION_ID, Location, ModelVersion
from model.posterior import LocationPosterior

# Versions are immutable once stored, so a loaded model is valid for as long as its database.
# Each thread keeps its own copies: posterior draws march through torch.func.functional_call,
# which swaps a module's parameters while it runs, so a model object shared by two threads
# (a request and the worker's batch, say) could march one thread's draw as the other's fitted
# weights, or fail half-way (seen: a 500 from the export while a batch job sampled).
_CACHE_SIZE = 8
_Cache = OrderedDict[tuple[str, int], LocationPosterior]
_local = threading.local()


def _thread_cache() -> _Cache:
    cache: _Cache | None = getattr(_local, "cache", None)
    if cache is None:
        cache = _local.cache = OrderedDict()
    return cache


def active_version_number(session: Session, location_id: int = DEFAULT_LOCATION_ID) -> int | None:
    """The location's active version (each location has its own models), None where none is."""
    return session.scalar(
        select(ModelVersion.version).where(
            ModelVersion.status == "active", ModelVersion.location_id == location_id
        )
    )


def active_versions(session: Session) -> dict[int, int]:
    """Every location's active version, by location id."""
    rows = session.execute(
        select(ModelVersion.location_id, ModelVersion.version).where(
            ModelVersion.status == "active"
        )
    )
    return {location_id: version for location_id, version in rows}


def active_versions_by_name(session: Session) -> dict[str, int]:
    """Every location's active version, by location name (sorted)."""
    rows = session.execute(
        select(Location.name, ModelVersion.version)
        .join(Location, Location.id == ModelVersion.location_id)
        .where(ModelVersion.status == "active")
    )
    return dict(sorted((name, version) for name, version in rows))


def require_active_version(session: Session, location_id: int = DEFAULT_LOCATION_ID) -> int:
    """The location's active version; raises ConflictError when none is (train one with POST
    /models/retrain)."""
    version = active_version_number(session, location_id)
    if version is None:
        where = "" if location_id == DEFAULT_LOCATION_ID else " at this location"
        latest = session.execute(
            select(ModelVersion.version, ModelVersion.status)
            .where(ModelVersion.location_id == location_id)
            .order_by(ModelVersion.version.desc())
            .limit(1)
        ).first()
        if latest is None:
            raise ConflictError(f"no model is active{where}: train one with POST /models/retrain")
        raise ConflictError(f"no model is active{where}: {latest_version_words(*latest)}")
    return version


def latest_version_words(version: int, status: str) -> str:
    """Why a location whose versions are all stored but none active has no model: a retrain
    would not help where the gate refused its latest, an activation would."""
    return (
        f"its latest, v{version}, is {status} "
        f"(GET /models/{version} says why; POST /models/{version}/activate serves it)"
    )


def location_of(session: Session, version: int) -> int:
    """The location a version was trained for and serves."""
    found = session.scalar(select(ModelVersion.location_id).where(ModelVersion.version == version))
    if found is None:
        raise NotFoundError(f"unknown model version {version}")
    return int(found)


def list_versions(session: Session) -> list[ModelVersion]:
    query = select(ModelVersion).options(defer(ModelVersion.weights)).order_by(ModelVersion.version)
    return list(session.scalars(query))


def get_version(session: Session, version: int) -> ModelVersion:
    query = select(ModelVersion).options(defer(ModelVersion.weights))
    found = session.scalars(query.where(ModelVersion.version == version)).one_or_none()
    if found is None:
        raise NotFoundError(f"unknown model version {version}")
    return found


def version_of_job(session: Session, job_id: str) -> int | None:
    """The version a retrain job stored, if any."""
    return session.scalar(select(ModelVersion.version).where(ModelVersion.job_id == job_id))


def _make_active(session: Session, version: int) -> None:
    session.execute(
        update(ModelVersion)
        .where(ModelVersion.version == version, ModelVersion.status != "active")
        .values(status="active", activated_at=datetime.now(UTC))
    )


def activate(session: Session, version: int, *, actor: audit.Actor) -> ModelVersion:
    """Make `version` the one that serves forecasts, whatever its promotion gate said (a
    rollback, or an admin's decision); the previously active one is retired.  Audited."""
    row = get_version(session, version)
    previous = active_version_number(session, row.location_id)
    gate = (row.metrics or {}).get("gate") or {}
    # Retire first: a partial unique index allows one active version at a time per location.
    session.execute(
        update(ModelVersion)
        .where(
            ModelVersion.status == "active",
            ModelVersion.location_id == row.location_id,
            ModelVersion.version != version,
        )
        .values(status="retired")
    )
    _make_active(session, version)
    detail = {"previous": previous, "gate_passed": gate.get("passed")}
    audit.record(session, actor, "model.activate", f"model/{version}", detail)
    session.commit()
    return get_version(session, version)


def promote(
    session: Session,
    version: int,
    *,
    actor: audit.Actor,
    expected_active: int | None,
    detail: dict[str, Any],
) -> bool:
    """Activate `version` only while `expected_active` is still the active version (the one its
    promotion gate compared it with): a compare-and-swap, so a version activated meanwhile is
    never silently replaced.  Returns whether it was activated; audited when it was."""
    if expected_active is None:
        swapped = active_version_number(session, location_of(session, version)) is None
    else:
        retired = session.execute(
            update(ModelVersion)
            .where(ModelVersion.version == expected_active, ModelVersion.status == "active")
            .values(status="retired")
        )
        swapped = retired.rowcount == 1  # type: ignore[attr-defined]
    if not swapped:
        session.rollback()
        return False
    _make_active(session, version)
    audit.record(
        session, actor, "model.promote", f"model/{version}", {"previous": expected_active, **detail}
    )
    try:
        session.commit()
    except IntegrityError:  # another version became active at the same moment
        session.rollback()
        return False
    return True


def retrain_result(
    version: int | None, outcome: str, reason: str, metrics: dict[str, Any]
) -> dict[str, Any]:
    """A retrain job's result for the version it stored (a fit, an analysis or a resumed
    attempt alike; None: a fit the gate refused before storing one): outcome one of
    activated, candidate, refused, superseded."""
    return {
        "model_version": version,
        "activated": outcome == "activated",
        "outcome": outcome,
        "reason": reason,
        "metrics": metrics,
    }


def store_version(
    session: Session,
    posterior: LocationPosterior,
    *,
    training: dict[str, Any],
    metrics: dict[str, Any],
    job_id: str | None,
    location_id: int = DEFAULT_LOCATION_ID,
) -> int:
    """Store a location's posterior (its model file) as a new candidate version of the
    location and return its number."""
    row = ModelVersion(
        location_id=location_id,
        status="candidate",
        spec=posterior.spec_dict(),
        training=training,
        metrics=metrics,
        weights=posterior.to_bytes(metrics),
        job_id=job_id,
    )
    session.add(row)
    session.commit()
    return row.version


def model_file(session: Session, version: int) -> bytes:
    """The version's model file (model.artifacts format), as `fleetpinn predict --model` reads it."""
    get_version(session, version)  # 404 for an unknown version
    weights = session.scalar(select(ModelVersion.weights).where(ModelVersion.version == version))
    assert weights is not None
    return weights


def load_posterior(session: Session, version: int) -> LocationPosterior:
    """The location's posterior a stored version holds (model.posterior), deserialised once per
    thread, process and database; its tracking prior from the version's metrics."""
    key = (str(session.get_bind().engine.url), version)
    cache = _thread_cache()
    if key in cache:
        cache.move_to_end(key)
        return cache[key]
    row = session.execute(
        select(ModelVersion.weights, ModelVersion.metrics).where(ModelVersion.version == version)
    ).one_or_none()
    if row is None or row.weights is None:
        raise NotFoundError(f"unknown model version {version}")
    entry = LocationPosterior.from_bytes(row.weights, row.metrics or {})
    cache[key] = entry
    while len(cache) > _CACHE_SIZE:
        cache.popitem(last=False)
    return entry
