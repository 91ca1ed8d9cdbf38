"""A retrain's stored version acted on: refilled and activated where asked and its gate passed,
whether the attempt that stored it is this one or one whose worker died.

A job whose worker died is claimed again (app.services.jobs.queue, once its heartbeat is stale).  If
that attempt had stored its version, the new one fits nothing (a job makes at most one
version): it reads the stored gate verdict and finishes as the dead attempt would have (the
fleet's refill, then the compare-and-swap against the version the gate compared with), so a
version that passed its gate becomes active with or without a restart, and one the gate refused
stays a candidate.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from sqlalchemy.orm import Session

from app.config import Settings
from app.services import audit
from app.services import models as model_service
from app.services.forecasts import cache_fill, forecast_cache
from app.services.jobs import analysis_model
from app.services.jobs import queue as jobs
from app.services.jobs.promotion import Gate
from app.services.records import locations
from app.tables import Job


def activate_if_passed(
    session: Session,
    version: int,
    gate: Gate,
    *,
    job_id: str | None,
    params: dict[str, Any],
    settings: Settings,
    progress: Callable[..., None],
    known: cache_fill.Known | None = None,
) -> tuple[str, str]:
    """Refill the fleet's forecasts under the stored `version` and activate it, if asked
    (params["activate"], default True) and the gate passed: (outcome, reason), outcome one of
    activated, candidate (not asked), refused (by the gate), superseded (another version became
    active while this one trained).  known: what the fit already read (app.services.forecasts.cache_fill)."""
    if params.get("activate", True) and gate.passed:
        # Filled before the switch: forecasts keep coming, warm, from the active version until
        # the new one is (a cache filled after it left every forecast cold meanwhile).
        forecast_cache.refresh(
            session,
            version,
            settings,
            progress=lambda p: progress(0.88 + 0.12 * p, "forecasting the fleet"),
            known=known,
            # tomorrow's risk (6 s of 300 tails) is the worker's: its daily warm runs for each
            # newly active version (app.worker)
            ahead=False,
        )
    return _promote(session, version, gate, job_id=job_id, params=params)


def resume(
    session: Session,
    version: int,
    *,
    job_id: str,
    params: dict[str, Any],
    settings: Settings,
    progress: Callable[..., None],
) -> dict[str, Any]:
    """The job result of a retrain whose earlier attempt stored `version` and died: the version
    acted on as that attempt would have (module docstring)."""
    stored = model_service.get_version(session, version)
    metrics = stored.metrics or {}
    earlier = "stored by an earlier attempt of this job, whose worker stopped"
    if stored.status == "active":  # it died after the switch: nothing left to do
        outcome, reason = "activated", f"{earlier} after activating it"
    elif analysis_model.is_analysis(session, version):
        location = locations.location_by_id(session, stored.location_id)
        outcome, reason = analysis_model.activate_analysis(
            session,
            location,
            version,
            settings,
            job_id=job_id,
            params=params,
            progress=progress,
            reason=str(metrics.get("analysis", "")),
        )
        reason = f"{reason} ({earlier})"
    else:
        progress(0.88, "storing the version")
        gate = Gate.from_dict(metrics["gate"])
        outcome, reason = activate_if_passed(
            session,
            version,
            gate,
            job_id=job_id,
            params=params,
            settings=settings,
            progress=progress,
        )
        reason = f"{reason} ({earlier})"
    return model_service.retrain_result(version, outcome, reason, metrics)


def _promote(
    session: Session,
    version: int,
    gate: Gate,
    *,
    job_id: str | None,
    params: dict[str, Any],
) -> tuple[str, str]:
    """Activate the stored candidate if asked and the gate passed (activate_if_passed's
    outcomes)."""
    if not params.get("activate", True):
        return "candidate", f"stored as a candidate, as asked (gate: {gate.reason})"
    if not gate.passed:
        named = ", ".join(
            f"{c['inspection']} ({c['candidate_error_pct']:.3g} % off)" for c in gate.culprits
        )
        driven = f"; driven by {named}" if named else ""
        if gate.flagged:
            driven += "; trained on flagged " + ", ".join(f["inspection"] for f in gate.flagged)
        return "refused", f"refused by the promotion gate: {gate.reason}{driven}"
    job = None if job_id is None else session.get(Job, job_id)
    requester = None if job is None else jobs.requested_by(session, job)
    promoted = model_service.promote(
        session,
        version,
        actor=requester or audit.local("retrain"),
        expected_active=gate.active_version,
        detail={"job_id": job_id, "gate": gate.reason},
    )
    if not promoted:
        return "superseded", (
            f"v{gate.active_version} was replaced while this retrain ran: compare again, or "
            f"activate v{version} with POST /models/{version}/activate"
        )
    return "activated", gate.reason
