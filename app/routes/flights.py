"""Flights: a JSON batch for one tail, a CSV/Parquet file for many; one flight read, corrected
or deleted."""

from __future__ import annotations

from fastapi import APIRouter, Response, UploadFile, status
from sqlalchemy.orm import Session

from app import budget
from app.deps import SessionDep, SettingsDep, Writer
from app.responses import INVALID_ROW, UNKNOWN_TAIL, Responses, errors
from app.schemas import FlightIn, IngestOut, TailPath
from app.schemas_ops import FlightOut, FlightPatch
from app.services.records import corrections, ingest, spectra, stored
from app.services.records.ingest import IngestResult

router = APIRouter(tags=["flights"])

_ERRORS: Responses = {
    201: {"model": IngestOut, "description": "Some flights were stored."},
    **errors(
        UNKNOWN_TAIL,
        (409, "A flight_id is already stored with other values."),
        INVALID_ROW,
    ),
}
_UPLOAD_ERRORS: Responses = {
    **_ERRORS,
    **errors((503, "The upload took longer than request_timeout_seconds; nothing was stored.")),
}
_ONE: dict[int | str, dict[str, object]] = {
    404: {"description": "Unknown tail or flight."},
    409: {"description": "The flight changed meanwhile: read it again."},
    **errors((422, "The corrected flight is invalid; unchanged.")),
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


def _out(session: Session, flight: stored.Flight) -> FlightOut:
    return FlightOut.model_validate(stored.flight(session, flight))


@router.post("/aircraft/{tail}/flights", responses=_ERRORS)
def post_flights(
    tail: TailPath,
    flights: list[FlightIn],
    session: SessionDep,
    settings: SettingsDep,
    actor: Writer,
    response: Response,
) -> IngestOut:
    """Store a batch of flights of one registered tail (exact re-sends count as duplicates)."""
    ingest.check_batch_size(len(flights), settings.max_batch_rows)
    records, recorded = spectra.with_ranges(tail, [f.model_dump() for f in flights], settings)
    frame = ingest.flights_frame(tail, records)
    result = ingest.ingest_flights(
        session,
        frame,
        source="body",
        create_tails=False,
        actor=actor,
        settings=settings,
        recorded=recorded,
    )
    return _answer(result, response)


@router.post("/flights/upload", responses=_UPLOAD_ERRORS)
def upload_flights(
    file: UploadFile,
    session: SessionDep,
    settings: SettingsDep,
    actor: Writer,
    response: Response,
) -> IngestOut:
    """Store flights of many tails from a CSV or Parquet file (the offline CLI's columns): the
    schema says a file is sent, its content is checked against the file contract (docs/api.md),
    and an empty file, a missing column or a bad row is a 422 naming the file and row."""
    # A time budget as for reads (app.limits times GETs alone): the upload checks it between its
    # parse, its cycles and its commit, so one out of time stops with nothing stored (503).
    try:
        with budget.deadline(settings.request_timeout_seconds):
            result = ingest.ingest_upload(
                session, file.filename, file.file, actor=actor, settings=settings
            )
    except budget.DeadlineExceeded as exc:
        raise budget.DeadlineExceeded(f"{exc}; nothing was stored") from exc
    return _answer(result, response)


@router.get("/aircraft/{tail}/flights/{flight_id}", responses={404: _ONE[404]})
def get_flight(tail: TailPath, flight_id: str, session: SessionDep) -> FlightOut:
    """One stored flight, with the key that stored it."""
    return _out(session, corrections.get_flight(session, tail, flight_id))


@router.patch("/aircraft/{tail}/flights/{flight_id}", responses=_ONE)
def correct_flight(
    tail: TailPath,
    flight_id: str,
    body: FlightPatch,
    session: SessionDep,
    settings: SettingsDep,
    actor: Writer,
) -> FlightOut:
    """Correct a stored flight (audited with its values before); its tail's forecasts are
    recomputed on their next request."""
    changes = body.model_dump(exclude_unset=True)
    flight = corrections.correct_flight(
        session, tail, flight_id, changes, actor=actor, settings=settings
    )
    return _out(session, flight)


@router.delete("/aircraft/{tail}/flights/{flight_id}", responses={404: _ONE[404]})
def delete_flight(tail: TailPath, flight_id: str, session: SessionDep, actor: Writer) -> FlightOut:
    """Remove a stored flight (audited with its values); answers the flight as it was."""
    return _out(session, corrections.delete_flight(session, tail, flight_id, actor=actor))
