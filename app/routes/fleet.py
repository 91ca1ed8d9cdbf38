"""Fleet-wide views: who to inspect next."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query

from app.deps import SessionDep, SettingsDep
from app.schemas import RankingItem, RankingOut
from app.services import forecast as forecast_service

router = APIRouter(prefix="/fleet", tags=["fleet"])


@router.get("/ranking", responses={409: {"description": "No active model."}})
def ranking(
    session: SessionDep,
    settings: SettingsDep,
    limit: Annotated[int, Query(ge=1, le=10_000)] = 20,
) -> RankingOut:
    """Tails most urgent first: earliest date at the critical crack, then the largest crack now."""
    version, critical, total, items = forecast_service.ranking(
        session, limit=limit, settings=settings
    )
    return RankingOut(
        model_version=version,
        critical_crack_m=critical,
        total=total,
        items=[
            RankingItem(
                rank=rank,
                tail=item.tail,
                crack_length_m=item.crack_length_m,
                critical_fraction=item.crack_length_m / critical,
                flights_to_critical=item.flights_to_critical,
                critical_date=item.critical_date,
                flights_flown=item.flights_flown,
                origin=item.origin,
                flights_per_day=item.flights_per_day,
            )
            for rank, item in enumerate(items, start=1)
        ],
    )
