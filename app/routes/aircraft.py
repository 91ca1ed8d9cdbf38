"""Aircraft registry."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Query, Response, status

from app.deps import Admin, SessionDep, SettingsDep, Writer
from app.responses import UNKNOWN_TAIL, errors
from app.schemas import AircraftIn, AircraftOut, AircraftPage, TailPath
from app.schemas_locations import CarriedIn, CarriedOut
from app.services.records import aircraft as aircraft_service
from app.services.records import aircraft_locations
from app.services.records.aircraft import AircraftSummary
from app.services.records.plausibility import Bounds

router = APIRouter(prefix="/aircraft", tags=["aircraft"])


def _out(summary: AircraftSummary) -> AircraftOut:
    return AircraftOut(
        tail=summary.tail,
        initial_crack_m=summary.initial_crack_m,
        created_at=summary.created_at,
        flight_count=summary.flight_count,
        last_flown_at=summary.last_flown_at,
        inspection_count=summary.inspection_count,
    )


@router.put("/{tail}", responses={201: {"model": AircraftOut}})
def put_aircraft(
    tail: TailPath,
    session: SessionDep,
    settings: SettingsDep,
    actor: Writer,
    response: Response,
    body: Annotated[AircraftIn | None, Body()] = None,
) -> AircraftOut:
    """Register a tail (201) or update it (200); an initial crack must lie below the critical."""
    body = body or AircraftIn()
    summary, created = aircraft_service.put_aircraft(
        session, tail, initial_crack_m=body.initial_crack_m, actor=actor, bounds=Bounds.of(settings)
    )
    if created:
        response.status_code = status.HTTP_201_CREATED
    return _out(summary)


@router.get("/{tail}/locations", responses=errors(UNKNOWN_TAIL))
def get_carried(tail: TailPath, session: SessionDep) -> CarriedOut:
    """The catalogue's locations this aircraft carries (all, unless it lists a subset)."""
    return CarriedOut(tail=tail, locations=aircraft_locations.carried(session, tail))


@router.put("/{tail}/locations", responses=errors(UNKNOWN_TAIL))
def put_carried(tail: TailPath, body: CarriedIn, session: SessionDep, actor: Writer) -> CarriedOut:
    """Give the aircraft a subset of the catalogue (null or []: every location); an unknown
    name is a 422 naming `locations`, nothing stored."""
    names = aircraft_locations.set_carried(session, tail, body.locations, actor=actor)
    return CarriedOut(tail=tail, locations=names)


@router.get("")
def list_aircraft(
    session: SessionDep,
    limit: Annotated[int, Query(ge=1, le=1000)] = 100,
    offset: Annotated[int, Query(ge=0, le=2**31 - 1)] = 0,
) -> AircraftPage:
    """Aircraft ordered by tail, a page at a time."""
    items, total = aircraft_service.list_aircraft(session, limit=limit, offset=offset)
    return AircraftPage(items=[_out(s) for s in items], total=total, limit=limit, offset=offset)


@router.get("/{tail}", responses=errors(UNKNOWN_TAIL))
def get_aircraft(tail: TailPath, session: SessionDep) -> AircraftOut:
    """One aircraft with its flight and inspection counts."""
    return _out(aircraft_service.get_aircraft(session, tail))


@router.delete("/{tail}", responses=errors(UNKNOWN_TAIL))
def delete_aircraft(tail: TailPath, session: SessionDep, actor: Admin) -> AircraftOut:
    """Remove a tail with its flights, inspections and forecasts (audited); admin keys only."""
    return _out(aircraft_service.delete_aircraft(session, tail, actor=actor))
