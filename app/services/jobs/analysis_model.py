"""A catalogued location's model before its first inspection: the catalogue's physics alone.

A damage-tolerance programme has a crack-growth analysis for every control point long before
anything is found there: the initial flaw grown under the recorded loads by the location's law,
stress transfer and geometry factors, to its critical crack.  Without one, a location added to
the catalogue stayed without an active model until its first inspection, and an aircraft's
summary left it out, governing or not (app.services.forecasts.aircraft_summary lists the locations with an
active version).  A retrain of such a location therefore stores that analysis as its version:
the physics kernel, nothing fitted; its tails drawn from the fleet spread's prior
(model.fleet_spread.spread_prior); and, since no crack has been measured, the geometry
factor's unknown trend (model.extrapolation) from the initial crack on, so the bands carry the
physics' own plausible range.  The first retrain after an inspection fits the location as
usual, gated against this version.

The default location keeps today's answer (a fleet without inspections has nothing to retrain
on: app.services.jobs.retrain.NoTrainingData), so existing clients see no change.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from sqlalchemy import exists, select
from sqlalchemy.orm import Session

from app.config import Settings
from app.services import audit
from app.services import models as model_service
from app.services.forecasts import forecast_cache
from app.services.records import locations
from app.services.records.carriage import carries
from app.tables import Aircraft, Flight
from model import posterior as door

ANALYSIS = "analysis"  # the version's training["kind"]: no inspections behind it


def carried_with_flights(session: Session, location_id: int) -> bool:
    """Whether some aircraft that carries the location has flights (an analysis has loads)."""
    query = select(Aircraft.id).where(
        exists().where(Flight.aircraft_id == Aircraft.id), carries(location_id)
    )
    return session.scalars(query.limit(1)).first() is not None


def is_analysis(session: Session, version: int) -> bool:
    """Whether the version is an analysis (no inspections behind it)."""
    return (model_service.get_version(session, version).training or {}).get("kind") == ANALYSIS


def analysis_model(physics: locations.Physics, settings: Settings) -> door.LocationPosterior:
    """The location's physics alone (its table of F, where it has one), its geometry factor's
    trend unknown from a0 on (the catalogue's F as declared), the fleet spread the settings
    assume."""
    return door.analysis(
        physics.law,
        physics.growth_law,
        slope_sd=settings.extrapolation_slope_sd,
        growth_sd=settings.growth_sd_prior,
        sizing=physics.sizing,
    )


def store_analysis(
    session: Session,
    location: locations.StoredLocation,
    settings: Settings,
    *,
    job_id: str | None,
    params: dict[str, Any],
    progress: Callable[..., None],
) -> dict[str, Any]:
    """Store (and unless params["activate"] is False, activate and forecast from) the
    location's analysis version; returns the job result."""
    physics = locations.physics(location, settings)
    posterior = analysis_model(physics, settings)
    assert posterior.tracking is not None
    reason = (
        f"no inspection at location {location.name!r} yet: the catalogue's physics alone "
        f"(the tails' growth drawn from the fleet spread's prior, the geometry factor's trend "
        f"unknown from the initial crack on)"
    )
    metrics: dict[str, Any] = {
        "analysis": reason,
        "tracking": posterior.tracking.to_dict(),
        **posterior.physics_summary(learned=False),
        "validation": {"count": 0},
    }
    training = {"kind": ANALYSIS, "kernel": "physics", "observations": 0}
    progress(0.5, "storing the analysis")
    version = model_service.store_version(
        session,
        posterior,
        training=training,
        metrics=metrics,
        job_id=job_id,
        location_id=location.id,
    )
    outcome, reason = activate_analysis(
        session,
        location,
        version,
        settings,
        job_id=job_id,
        params=params,
        progress=progress,
        reason=reason,
    )
    return model_service.retrain_result(version, outcome, reason, metrics)


def activate_analysis(
    session: Session,
    location: locations.StoredLocation,
    version: int,
    settings: Settings,
    *,
    job_id: str | None,
    params: dict[str, Any],
    progress: Callable[..., None],
    reason: str,
) -> tuple[str, str]:
    """Refill under the stored analysis `version` and activate it, unless params["activate"] is
    False or a version fitted to inspections is active there: (outcome, reason)."""
    active = model_service.active_version_number(session, location.id)
    fitted_active = active is not None and not is_analysis(session, active)
    if not params.get("activate", True):
        outcome, reason = "candidate", f"stored as a candidate, as asked ({reason})"
    elif fitted_active:
        # a version fitted to inspections since removed: not replaced without a look
        outcome = "candidate"
        reason = (
            f"v{active} was fitted to inspections at {location.name!r}, none of which remain; "
            f"activate this analysis with POST /models/{version}/activate ({reason})"
        )
    else:
        forecast_cache.refresh(
            session,
            version,
            settings,
            progress=lambda p: progress(0.5 + 0.5 * p, "forecasting the fleet"),
            ahead=False,
        )
        promoted = model_service.promote(
            session,
            version,
            actor=audit.local("retrain"),
            expected_active=active,
            detail={"job_id": job_id, "analysis": reason},
        )
        outcome = "activated" if promoted else "superseded"
        if not promoted:
            reason = f"another version became active at {location.name!r} meanwhile ({reason})"
    return outcome, reason
