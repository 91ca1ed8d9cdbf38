"""Flight ingestion: a JSON batch for one tail, or a CSV/Parquet file for many."""

from __future__ import annotations

from fastapi import APIRouter, Response, UploadFile, status

from app.deps import SessionDep
from app.schemas import FlightIn, IngestOut, RecordErrorOut, TailPath
from app.services import ingest
from app.services.ingest import IngestResult

router = APIRouter(tags=["flights"])

_ERRORS: dict[int | str, dict[str, object]] = {
    201: {"model": IngestOut, "description": "Some flights were stored."},
    404: {"description": "Unknown tail."},
    409: {"description": "A flight_id is already stored with other values."},
    422: {"model": RecordErrorOut, "description": "An invalid row; nothing was stored."},
}


def _answer(result: IngestResult, response: Response) -> IngestOut:
    # 201 when something was stored; 200 for a pure re-send (idempotent retry).
    if result.inserted:
        response.status_code = status.HTTP_201_CREATED
    return IngestOut(
        inserted=result.inserted,
        duplicates=result.duplicates,
        aircraft_created=result.aircraft_created,
    )


@router.post("/aircraft/{tail}/flights", responses=_ERRORS)
def post_flights(
    tail: TailPath, flights: list[FlightIn], session: SessionDep, response: Response
) -> IngestOut:
    """Store a batch of flights of one registered tail (exact re-sends count as duplicates)."""
    frame = ingest.flights_frame(tail, [f.model_dump() for f in flights])
    result = ingest.ingest_flights(session, frame, source="body", create_tails=False)
    return _answer(result, response)


@router.post("/flights/upload", responses=_ERRORS)
def upload_flights(file: UploadFile, session: SessionDep, response: Response) -> IngestOut:
    """Store flights of many tails from a CSV or Parquet file (the offline CLI's columns)."""
    return _answer(ingest.ingest_upload(session, file.filename, file.file), response)
