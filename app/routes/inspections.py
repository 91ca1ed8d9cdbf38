"""Crack measurements of one tail: record (compared with the forecast), list, read, correct,
delete."""

from __future__ import annotations

from fastapi import APIRouter, Response, status
from sqlalchemy.orm import Session

from app.deps import SessionDep, SettingsDep, Writer
from app.responses import INVALID_ROW, UNKNOWN_TAIL, errors
from app.schemas import (
    InspectionIn,
    InspectionIngestOut,
    InspectionOut,
    TailPath,
)
from app.schemas_ops import AssessmentOut, InspectionPatch
from app.services.records import aircraft as aircraft_service
from app.services.records import corrections, ingest, stored

router = APIRouter(prefix="/aircraft/{tail}/inspections", tags=["inspections"])

_ONE: dict[int | str, dict[str, object]] = {
    404: {"description": "Unknown tail or inspection."},
    409: {"description": "The inspection changed meanwhile: read it again."},
    **errors((422, "The corrected inspection is invalid.")),
}


def _one(session: Session, inspection: stored.Inspection) -> InspectionOut:
    return InspectionOut.model_validate(stored.inspections(session, [inspection])[0])


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    responses={
        200: {"model": InspectionIngestOut, "description": "Every inspection was already stored."},
        **errors(
            UNKNOWN_TAIL,
            (409, "An inspection_id is already stored with other values."),
            INVALID_ROW,
        ),
    },
)
def post_inspections(
    tail: TailPath,
    inspections: InspectionIn | list[InspectionIn],
    session: SessionDep,
    settings: SettingsDep,
    actor: Writer,
    response: Response,
) -> InspectionIngestOut:
    """Record one inspection (or a list); 201 when stored, 200 for an exact re-send.  Each new
    one is compared with the tail's forecast, and flagged when it disagrees strongly."""
    items = inspections if isinstance(inspections, list) else [inspections]
    ingest.check_batch_size(len(items), settings.max_batch_rows)
    frame = ingest.inspections_frame(tail, [i.model_dump() for i in items])
    result = ingest.ingest_inspections(
        session, frame, source="body", actor=actor, settings=settings
    )
    if not result.inserted:
        response.status_code = status.HTTP_200_OK
    return InspectionIngestOut(
        inserted=result.inserted,
        duplicates=result.duplicates,
        aircraft_created=0,
        assessments=[
            AssessmentOut(
                inspection_id=a.inspection_id,
                forecast_crack_m=a.forecast_crack_m,
                forecast_z=a.forecast_z,
                flagged=a.flagged,
            )
            for a in result.assessments
        ],
    )


@router.get("", responses=errors(UNKNOWN_TAIL))
def list_inspections(tail: TailPath, session: SessionDep) -> list[InspectionOut]:
    """The tail's inspections in time order."""
    aircraft = aircraft_service.find_aircraft(session, tail)
    rows = ingest.list_inspections(session, aircraft.id)
    return [InspectionOut.model_validate(i) for i in stored.inspections(session, rows)]


@router.get("/{inspection_id}", responses={404: _ONE[404]})
def get_inspection(tail: TailPath, inspection_id: str, session: SessionDep) -> InspectionOut:
    """One stored inspection, with its comparison with the forecast and who recorded it."""
    return _one(session, corrections.get_inspection(session, tail, inspection_id))


@router.patch("/{inspection_id}", responses=_ONE)
def correct_inspection(
    tail: TailPath,
    inspection_id: str,
    body: InspectionPatch,
    session: SessionDep,
    settings: SettingsDep,
    actor: Writer,
) -> InspectionOut:
    """Correct a stored inspection (audited with its values before); it is checked as a new one
    is and compared with the forecast again."""
    changes = body.model_dump(exclude_unset=True)
    inspection = corrections.correct_inspection(
        session, tail, inspection_id, changes, actor=actor, settings=settings
    )
    return _one(session, inspection)


@router.delete("/{inspection_id}", responses={404: _ONE[404]})
def delete_inspection(
    tail: TailPath, inspection_id: str, session: SessionDep, actor: Writer
) -> InspectionOut:
    """Remove a stored inspection (audited with its values); answers it as it was."""
    return _one(session, corrections.delete_inspection(session, tail, inspection_id, actor=actor))
