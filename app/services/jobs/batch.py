"""The forecast-batch job: every tail's cached forecast made current under one model version.

A valid cached row is current by construction (app.services.forecasts.forecast_cache: every write of a
tail's records advances or drops its rows), so the batch fills only the tails without one (a
new version, new tails, rows a write dropped) and then the default horizon's risk as of today
where it is not stored yet: what every ranking and export reads.  Recomputing a current row
gives the same values (its draws are seeded per tail) at ~0.35 s a tail on the demo fleet, so
`refresh` recomputes every row only when asked (after a change of the settings a row is
computed under, such as the utilization window).  Tomorrow's risk is left to the worker's daily
warm (app.worker), as after a retrain: it was a third of the batch's sampling.

Progress: the share of tails done, with the stage in words ("forecasting tails 100/300").
"""

from __future__ import annotations

from collections.abc import Callable

from sqlalchemy import exists, select
from sqlalchemy.orm import Session

from app.config import Settings
from app.services import models as model_service
from app.services.forecasts import cache_rows, forecast_cache
from app.services.ranking import order as ranking
from app.services.records import locations
from app.tables import Aircraft, Flight

# Shares of the progress bar: filling rows, then sampling today's risk of the kept ones.
_FILLING = 0.9


def run_batch(
    session: Session,
    *,
    version: int | None,
    settings: Settings,
    progress: Callable[[float, str], None],
    refresh: bool = False,
) -> dict[str, object]:
    """Make every tail's cached forecast under `version` (default: the active one) current, and
    its risk over forecast_horizon_days as of today stored.  refresh: recompute every row, not
    only the missing ones.  Returns the version, the tails forecast and how many were computed
    (`filled`) or already current (`kept`).  With no version asked and several locations with
    models, every location's active version in turn: the default location's counts as before,
    and `locations` gives each location's (its (tail, location) rows).  Raises ConflictError
    (no active model) or NotFoundError (unknown version)."""
    active = model_service.active_versions(session)
    if version is None and len(active) == 1:  # the one location with a model, default or not
        version = next(iter(active.values()))
    if version is not None or len(active) < 2:
        return _run_one(session, version, settings, progress, refresh)
    names = locations.names_of(session, list(active))
    each: dict[str, dict[str, object]] = {}
    for k, (location_id, version_of) in enumerate(sorted(active.items())):

        def part(share: float, stage: str, k: int = k, name: str = names[location_id]) -> None:
            progress((k + share) / len(active), f"{name}: {stage}")

        each[names[location_id]] = _run_one(session, version_of, settings, part, refresh)
    first = each[names[min(active)]]
    return {**first, "locations": each}


def _run_one(
    session: Session,
    version: int | None,
    settings: Settings,
    progress: Callable[[float, str], None],
    refresh: bool,
) -> dict[str, object]:
    version = version or model_service.require_active_version(session)
    model_service.get_version(session, version)
    flown = select(Aircraft.id).where(exists().where(Flight.aircraft_id == Aircraft.id))
    tails = list(session.scalars(flown.order_by(Aircraft.id)))
    todo = tails if refresh else sorted(cache_rows.missing(session, version, settings))
    total = len(todo)
    progress(0.0, f"{len(tails) - total} of {len(tails)} tails current; forecasting {total}")

    def filled(share: float) -> None:
        progress(_FILLING * share, f"forecasting tails {round(share * total)}/{total}")

    stored = 0
    if todo:
        stored = forecast_cache.refresh(
            session, version, settings, aircraft_ids=todo, progress=filled, ahead=False
        )
    progress(_FILLING, "risk as of today")
    horizon = min(settings.forecast_horizon_days, settings.max_horizon_days)
    ranking.ordered(session, version, settings, horizon, "risk", settings.today())
    progress(1.0, "done")
    return {
        "model_version": version,
        "forecasts": len(tails),
        "filled": stored,
        "kept": len(tails) - total,
    }
