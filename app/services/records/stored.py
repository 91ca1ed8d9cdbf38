"""Stored rows as the API reports them: records named field for field as their schemas
(FlightOut, InspectionOut, JobOut, ModelVersionOut), which validate from them
(`from_attributes`), with what the rows alone do not hold: who recorded or requested them (the
audit log), a retrain's outcome, a version's gate verdict.  Routes then stay a service call and
a schema, and never read the tables' classes themselves.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from datetime import datetime
from typing import Any

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.services import audit
from app.services.records import locations
from app.tables import Flight, Inspection, Job, ModelVersion

# The rows the services hand the routes, by the names the routes know them by.
Version = ModelVersion


@dataclass(frozen=True)
class StoredFlight:
    flight_id: str
    flown_at: datetime
    stress_range_mpa: float
    mission: str | None
    recorded_by: str | None


def flight(session: Session, row: Flight) -> StoredFlight:
    return StoredFlight(
        flight_id=row.flight_id,
        flown_at=row.flown_at,
        stress_range_mpa=row.stress_range_mpa,
        mission=row.mission,
        recorded_by=audit.actors(session, [row.audit_id]).get(row.audit_id or -1),
    )


@dataclass(frozen=True)
class StoredInspection:
    inspection_id: str
    inspected_at: datetime
    crack_length_m: float | None
    detected: bool
    detection_threshold_m: float | None
    pod_a50_m: float | None
    pod_a90_m: float | None
    repaired: bool
    crack_after_repair_m: float | None
    location: str
    forecast_crack_m: float | None
    forecast_z: float | None
    flagged: bool
    recorded_by: str | None


def inspections(session: Session, rows: Sequence[Inspection]) -> list[StoredInspection]:
    """The rows with who recorded each (one query for all)."""
    recorded_by = audit.actors(session, [row.audit_id for row in rows])
    location = locations.names_of(session, [row.location_id for row in rows])
    return [
        StoredInspection(
            inspection_id=row.inspection_id,
            inspected_at=row.inspected_at,
            crack_length_m=row.crack_length_m,
            detected=row.detected,
            detection_threshold_m=row.detection_threshold_m,
            pod_a50_m=row.pod_a50_m,
            pod_a90_m=row.pod_a90_m,
            repaired=row.repaired,
            crack_after_repair_m=row.crack_after_repair_m,
            location=location[row.location_id],
            forecast_crack_m=row.forecast_crack_m,
            forecast_z=row.forecast_z,
            flagged=row.flagged,
            recorded_by=recorded_by.get(row.audit_id or -1),
        )
        for row in rows
    ]


@dataclass(frozen=True)
class StoredJob:
    job_id: str
    kind: str
    status: str
    progress: float
    stage: str | None
    params: dict[str, Any]
    model_version: int | None
    outcome: str | None
    outcome_reason: str | None
    metrics: dict[str, Any] | None
    result: dict[str, Any] | None
    error: str | None
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    requested_by: str | None


def jobs(session: Session, rows: Sequence[Job]) -> list[StoredJob]:
    """The rows with who requested each and, for a retrain, its outcome (app.services.jobs.retrain
    stores it in the job's result)."""
    requested_by = audit.actors(session, [row.audit_id for row in rows])
    out = []
    for row in rows:
        result = row.result or {}
        out.append(
            StoredJob(
                job_id=row.id,
                kind=row.kind,
                status=row.status,
                progress=row.progress,
                stage=row.stage,
                params=row.params,
                model_version=result.get("model_version"),
                outcome=result.get("outcome"),
                outcome_reason=result.get("reason"),
                metrics=result.get("metrics"),
                result=row.result,
                error=row.error,
                created_at=row.created_at,
                started_at=row.started_at,
                finished_at=row.finished_at,
                requested_by=requested_by.get(row.audit_id or -1),
            )
        )
    return out


def job_counts(session: Session) -> dict[str, int]:
    """How many jobs are in each status (the metrics' gauge)."""
    rows = session.execute(select(Job.status, func.count()).group_by(Job.status))
    return {status: count for status, count in rows}


@dataclass(frozen=True)
class StoredVersion:
    version: int
    status: str
    created_at: datetime
    activated_at: datetime | None
    spec: dict[str, Any]
    training: dict[str, Any]
    metrics: dict[str, Any]
    gate: dict[str, Any] | None
    job_id: str | None
    location: str | None = None  # the location it serves (None: not read)


def versions(session: Session, rows: list[ModelVersion]) -> list[StoredVersion]:
    """version() of each row, with the name of the location it was trained for and serves."""
    names = locations.names_of(session, sorted({row.location_id for row in rows}))
    return [replace(version(row), location=names.get(row.location_id)) for row in rows]


def version(row: ModelVersion) -> StoredVersion:
    """A model version with the promotion gate's verdict stored in its metrics (None: stored
    before the gate)."""
    return StoredVersion(
        version=row.version,
        status=row.status,
        created_at=row.created_at,
        activated_at=row.activated_at,
        spec=row.spec,
        training=row.training,
        metrics=row.metrics,
        gate=row.metrics.get("gate"),
        job_id=row.job_id,
    )
