"""The fleet's catalogue of control points: every aircraft carries its locations."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Response, status
from fastapi.exceptions import RequestValidationError

from app.config import Settings
from app.deps import Admin, SessionDep, SettingsDep, Writer
from app.responses import errors
from app.schemas_locations import (
    CrackCaseBetaOut,
    CriticalCrackOut,
    LocationIn,
    LocationOut,
    LocationPath,
)
from app.services.records import location_cracks, location_delete
from app.services.records import locations as location_service
from app.services.records.locations import StoredLocation
from model.materials import law_for, material
from model.records import RecordError

router = APIRouter(prefix="/locations", tags=["locations"])

_UNKNOWN = (404, "Unknown location.")


@router.put(
    "/{name}",
    responses={
        201: {"model": LocationOut},
        **errors((422, "The entry is invalid; nothing stored.")),
    },
)
def put_location(
    name: LocationPath,
    body: LocationIn,
    session: SessionDep,
    settings: SettingsDep,
    actor: Writer,
    response: Response,
) -> LocationOut:
    """Add a control point to the catalogue (201) or replace its entry (200); a critical crack
    at or below the initial one (the model's where one is null), or a material the table
    (with FLEETPINN_MATERIALS_FILE's rows) lacks, is a 422 naming the field."""
    _check_material(body.material, settings)
    _check_nasgro(body, settings)
    stored, created = location_service.put_location(
        session, name, body.model_dump(mode="json"), actor=actor, settings=settings
    )
    if created:
        response.status_code = status.HTTP_201_CREATED
    return _out(stored, settings)


def _check_material(name: str | None, settings: Settings) -> None:
    """Here, not in the schema: the names known depend on the settings' materials file (and a
    stored entry is answered even after its row left the file)."""
    if name is None:
        return
    try:
        material(name, settings.materials_file)
    except ValueError as exc:
        error = {"type": "value_error", "loc": ("body", "material"), "input": name}
        raise RequestValidationError([{**error, "msg": f"Value error, {exc}"}]) from exc


def _check_nasgro(body: LocationIn, settings: Settings) -> None:
    """NASGRO's equation reads its terms from the entry's material (or the settings'): a row
    without them is a 422 naming growth_law, as the settings refuse it at start."""
    if body.growth_law is None or body.growth_law.law != "nasgro":
        return
    law = settings.law()
    if body.material is not None:
        law = law_for(body.material, law, settings.materials_file)
    if law.nasgro is None:
        reason = (
            f"law nasgro needs a material whose row has NASGRO terms; "
            f"{body.material or settings.material!r} has none (the shipped table has none: "
            "a row of FLEETPINN_MATERIALS_FILE)"
        )
        error = {"type": "value_error", "loc": ("body", "growth_law"), "input": "nasgro"}
        raise RequestValidationError([{**error, "msg": f"Value error, {reason}"}])


@router.get("")
def list_locations(session: SessionDep, settings: SettingsDep) -> list[LocationOut]:
    """The catalogue, by name; 'default' is the location of requests that name none."""
    return [_out(s, settings) for s in location_service.list_locations(session)]


@router.delete(
    "/{name}",
    responses=errors(_UNKNOWN, (409, "Records still refer to it (the detail says which).")),
)
def delete_location(
    name: LocationPath,
    session: SessionDep,
    actor: Admin,
    force: Annotated[bool, Query()] = False,
) -> LocationOut:
    """Remove a catalogue entry (audited; admin keys only): refused with a 409 naming what
    still refers to it (aircraft listing it, its inspections, its model versions, its queued
    retrains), unless force=true, which removes those records with it."""
    return LocationOut.model_validate(
        location_delete.delete_location(session, name, force=force, actor=actor)
    )


@router.get("/{name}", responses=errors(_UNKNOWN))
def get_location(name: LocationPath, session: SessionDep, settings: SettingsDep) -> LocationOut:
    """One catalogue entry, with its crack case's beta(a) and a_crit where it has one."""
    return _out(location_service.get_location(session, name), settings)


def _out(stored: StoredLocation, settings: Settings) -> LocationOut:
    """The entry with what its crack case computes (a case the settings no longer allow,
    e.g. a changed initial crack, is answered with its reason, not a 500)."""
    out = LocationOut.model_validate(stored)
    try:
        answer = location_cracks.crack_case_answer(stored, settings)
    except RecordError as exc:
        return out.model_copy(update={"crack_case_error": str(exc)})
    if answer is None:
        return out
    curve = answer.curve
    beta = CrackCaseBetaOut(
        crack_length_m=list(curve.table.crack_length_m),
        beta=list(curve.table.factor),
        max_relative_error=curve.max_relative_error,
        validity_limit_m=curve.validity.crack_length_m,
        validity_reason=curve.validity.reason,
        warning=curve.warning,
        residual_strength_mpa=None
        if answer.residual_strength_mpa is None
        else list(answer.residual_strength_mpa),
    )
    critical = None
    if answer.critical is not None:
        assert answer.toughness is not None and answer.residual_at_initial is not None
        assert answer.limit_stress_mpa is not None
        critical = CriticalCrackOut(
            crack_length_m=answer.critical.crack_length_m,
            criterion=answer.critical.criterion,
            fracture_crack_m=answer.critical.fracture_crack_m,
            yield_crack_m=answer.critical.yield_crack_m,
            toughness_mpa_sqrt_m=answer.toughness.fracture_toughness_mpa_sqrt_m,
            toughness_kind=answer.toughness.kind,
            yield_strength_mpa=answer.toughness.yield_strength_mpa,
            residual_strength_at_initial_mpa=answer.residual_at_initial.stress_mpa,
            criterion_at_initial=answer.residual_at_initial.criterion,
            margin_at_initial=answer.residual_at_initial.margin_over(answer.limit_stress_mpa),
            warning=answer.critical.warning,
        )
    return out.model_copy(update={"crack_case_beta": beta, "critical_crack": critical})
