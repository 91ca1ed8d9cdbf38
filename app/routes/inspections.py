"""Crack measurements of one tail."""

from __future__ import annotations

from fastapi import APIRouter, Response, status

from app.deps import SessionDep
from app.schemas import IngestOut, InspectionIn, InspectionOut, RecordErrorOut, TailPath
from app.services import aircraft as aircraft_service
from app.services import ingest

router = APIRouter(prefix="/aircraft/{tail}/inspections", tags=["inspections"])


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    responses={
        200: {"model": IngestOut, "description": "Every inspection was already stored."},
        404: {"description": "Unknown tail."},
        409: {"description": "An inspection_id is already stored with other values."},
        422: {"model": RecordErrorOut, "description": "An invalid row; nothing was stored."},
    },
)
def post_inspections(
    tail: TailPath,
    inspections: InspectionIn | list[InspectionIn],
    session: SessionDep,
    response: Response,
) -> IngestOut:
    """Record one inspection (or a list); 201 when stored, 200 for an exact re-send."""
    items = inspections if isinstance(inspections, list) else [inspections]
    frame = ingest.inspections_frame(tail, [i.model_dump() for i in items])
    result = ingest.ingest_inspections(session, frame, source="body")
    if not result.inserted:
        response.status_code = status.HTTP_200_OK
    return IngestOut(inserted=result.inserted, duplicates=result.duplicates, aircraft_created=0)


@router.get("")
def list_inspections(tail: TailPath, session: SessionDep) -> list[InspectionOut]:
    """The tail's inspections in time order."""
    aircraft = aircraft_service.find_aircraft(session, tail)
    return [
        InspectionOut(
            inspection_id=i.inspection_id,
            inspected_at=i.inspected_at,
            crack_length_m=i.crack_length_m,
            detected=i.detected,
            detection_threshold_m=i.detection_threshold_m,
            pod_a50_m=i.pod_a50_m,
            pod_a90_m=i.pod_a90_m,
            repaired=i.repaired,
            crack_after_repair_m=i.crack_after_repair_m,
        )
        for i in ingest.list_inspections(session, aircraft.id)
    ]
