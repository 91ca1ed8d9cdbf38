"""Fleet-wide views: who to inspect next."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Query, Response

from app.deps import AsOf, SessionDep, SettingsDep
from app.responses import NO_MODEL, errors
from app.routes.forecasts import band_out, flights_out
from app.schemas_forecasts import DateQuantiles, LastInspectionOut, RankingItem, RankingOut
from app.services import ranking as ranking_service
from app.services.risk import as_of_time

router = APIRouter(prefix="/fleet", tags=["fleet"])


@router.get("/ranking", response_model=RankingOut, responses=errors(NO_MODEL))
def ranking(
    session: SessionDep,
    settings: SettingsDep,
    as_of: AsOf,
    limit: Annotated[int, Query(ge=1, le=10_000)] = 20,
    horizon_days: Annotated[int, Query(ge=1, le=36_500)] = 365,
    by: Literal["risk", "crack", "due"] = "risk",
) -> Response:
    """Tails by risk (P(critical within the horizon), then p95 crack), crack or due date."""
    horizon_days = min(horizon_days, settings.max_horizon_days)
    version, critical, total, items = ranking_service.ranking(
        session, limit=limit, settings=settings, horizon_days=horizon_days, by=by, as_of=as_of
    )
    answer = RankingOut(
        model_version=version,
        critical_crack_m=critical,
        horizon_days=horizon_days,
        as_of=as_of_time(as_of),
        by=by,
        total=total,
        items=[
            RankingItem(
                rank=rank,
                tail=item.tail,
                crack_length_m=item.crack_length_m,
                crack_length_band=band_out(item.risk.crack_now),
                critical_fraction=item.crack_length_m / critical,
                crack_as_of_band=band_out(item.risk.crack_as_of),
                crack_at_horizon_band=band_out(item.risk.crack_at_horizon),
                prob_critical=item.risk.prob_critical,
                inspect_by=item.inspect_by,
                overdue=item.overdue,
                flights_to_critical=item.flights_to_critical,
                critical_date=item.critical_date,
                flights_to_critical_quantiles=flights_out(item.risk),
                critical_date_quantiles=DateQuantiles(
                    p05=item.critical_dates[0],
                    p50=item.critical_dates[1],
                    p95=item.critical_dates[2],
                ),
                last_inspection=None
                if item.last_inspection is None
                else LastInspectionOut(
                    inspection_id=item.last_inspection.inspection_id,
                    inspected_at=item.last_inspection.inspected_at,
                    detected=item.last_inspection.detected,
                    crack_length_m=item.last_inspection.crack_length_m,
                    repaired=item.last_inspection.repaired,
                ),
                flagged_inspection_ids=list(item.flagged_inspection_ids),
                flights_flown=item.flights_flown,
                origin=item.origin,
                flights_per_day=item.flights_per_day,
            )
            for rank, item in enumerate(items, start=1)
        ],
    )
    # Encoded here, once: built from its schema, it needs no second validation (FastAPI's, on
    # one more request thread).
    return Response(answer.model_dump_json(by_alias=True), media_type="application/json")
