"""OpenAPI documentation of the error answers that app.main and app.limits produce."""

from __future__ import annotations

from typing import Any

from app.schemas import ErrorOut, InvalidOut

Responses = dict[int | str, dict[str, Any]]

UNKNOWN_TAIL = (404, "Unknown tail.")
UNKNOWN_VERSION = (404, "Unknown model version.")
UNKNOWN_JOB = (404, "Unknown job.")
NO_MODEL = (409, "No active model.")
INVALID_ROW = (422, "An invalid row or request; nothing was stored.")
QUEUE_FULL = (429, "The job queue holds max_queued_jobs queued jobs; nothing was queued.")


def errors(*answers: tuple[int, str]) -> Responses:
    """Responses documenting these (status, description) errors with their body schemas."""
    return {
        code: {"model": InvalidOut if code == 422 else ErrorOut, "description": text}
        for code, text in answers
    }


# Every API route (app.main includes the routers with it): the limits of app.limits and the
# request validation of FastAPI; a route's own entries override these.
COMMON = errors(
    (400, "The body could not be read (e.g. JSON that is not UTF-8)."),
    (401, "No valid API key (Authorization: Bearer KEY)."),
    (403, "The key's role may not do this."),
    (413, "The request body is larger than its limit (max_upload_bytes, max_body_bytes)."),
    (422, "The request does not fit its schema."),
    (503, "A read took longer than request_timeout_seconds."),
)
