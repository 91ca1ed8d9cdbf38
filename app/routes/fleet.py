"""Fleet-wide views: who to inspect next."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Response

from app.deps import AsOf, HorizonDays, SessionDep, SettingsDep
from app.responses import NO_MODEL, errors
from app.schemas_forecasts import RankingOut
from app.services.forecasts import reports
from app.services.ranking import ranking_answers

router = APIRouter(prefix="/fleet", tags=["fleet"])


@router.get("/ranking", response_model=RankingOut, responses=errors(NO_MODEL))
def ranking(
    session: SessionDep,
    settings: SettingsDep,
    horizon_days: HorizonDays,
    as_of: AsOf,
    limit: Annotated[int, Query(ge=1, le=10_000)] = 20,
    by: Literal["risk", "crack", "due"] = "risk",
) -> Response:
    """Tails by risk (P(critical within the horizon), then p95 crack), crack or due date."""

    def encoded(ranked: ranking_answers.Answer) -> bytes:
        report = reports.ranking_report(
            ranked,
            horizon_days=horizon_days,
            as_of=as_of,
            by=by,
            stale_after_days=settings.stale_after_days,
        )
        answer = RankingOut.model_validate(report)
        # Encoded here, once: built from its schema, it needs no second validation (FastAPI's,
        # on one more request thread).  A one-location ranking's rows name no location, and a
        # row without a limit stress no residual strength: as before.
        rows = any(item.location is not None for item in answer.items)
        located = set() if rows else {"location", "model_version", "critical_crack_m"}
        strong = [item.residual_strength is not None for item in answer.items]
        absent: dict[Any, set[str]] = {"__all__": located | {"residual_strength"}}
        if any(strong):  # per row: those without a limit stress leave the key out
            each = [located if has else located | {"residual_strength"} for has in strong]
            absent = {k: keys for k, keys in enumerate(each) if keys}
        return answer.model_dump_json(by_alias=True, exclude={"items": absent}).encode()

    body = ranking_answers.encoded_ranking(
        session,
        limit=limit,
        settings=settings,
        horizon_days=horizon_days,
        by=by,
        as_of=as_of,
        encode=encoded,
    )
    return Response(body, media_type="application/json")
