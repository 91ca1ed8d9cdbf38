"""The forecast-batch job: every tail's cached forecast filled under one model version."""

from __future__ import annotations

from collections.abc import Callable

from sqlalchemy.orm import Session

from app.config import Settings
from app.services import forecast_cache
from app.services import models as model_service


def run_batch(
    session: Session, *, version: int | None, settings: Settings, progress: Callable[..., None]
) -> dict[str, object]:
    """Forecast the whole fleet under `version` (default: the active one) and store the results.

    Raises ConflictError (no active model) or NotFoundError (unknown version).
    """
    version = version or model_service.require_active_version(session)
    model_service.get_version(session, version)
    progress(0.0, "forecasting the fleet")
    stored = forecast_cache.refresh(session, version, settings, progress=progress)
    return {"model_version": version, "forecasts": stored}
