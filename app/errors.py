"""Domain errors raised by services; app.main maps them to HTTP answers."""

from __future__ import annotations


class NotFoundError(LookupError):
    """The named resource does not exist (HTTP 404)."""


class ConflictError(RuntimeError):
    """The request contradicts stored state (HTTP 409)."""


class QueueFull(RuntimeError):
    """The job queue holds its most queued jobs (HTTP 429); nothing was queued."""
