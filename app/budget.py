"""The budget of one request: how far its inputs may reach, how long and how much memory its
sampling may take.

Inputs that set the amount of work are bounded where they enter: the as-of date lies within
[earliest_record_date, today + max_horizon_days] (422 naming `as_of`), and one tail's sampled
future (lead + horizon days at its rate) holds at most max_sampled_flights() flights per draw
(422 naming `as_of` and `horizon_days`).  Time: a request that carries a deadline (app.limits
sets one on every timed read; the planned forecast sets its own) checks it between the pieces of
its sampling (check()), so work past request_timeout_seconds stops instead of running on after
its 503.  Memory: a march holds about _BYTES_PER_LANE_FLIGHT bytes per (sample x tail) lane and
flight, so tails are sampled in groups whose lanes x flights stay under max_sampling_bytes
(tails_per_march).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from datetime import date, timedelta
from typing import Any

from app.config import Settings
from model.posterior import LANES_PER_MARCH

# A march keeps the stacked future loads and the trajectory of each lane: two float64 per
# flight (model.prognosis.LANES_PER_MARCH's comment); the quantiles read from them add a copy.
_BYTES_PER_LANE_FLIGHT = 24

# (monotonic time the request's work must end by, its time limit in seconds)
_deadline: ContextVar[tuple[float, float] | None] = ContextVar("fleetpinn_deadline", default=None)
# set by a worker thread (app.worker): once the process stops, its work ends at the next check()
# (tails_per_march: a check at least every STOPPABLE_TAILS tails sampled)
STOPPABLE_TAILS = 16
_stopping: ContextVar[threading.Event | None] = ContextVar("fleetpinn_stopping", default=None)


class DeadlineExceeded(RuntimeError):
    """The request's time ran out (HTTP 503); what it sampled so far may be kept."""


class Stopped(DeadlineExceeded):
    """The process is stopping: a worker thread's sampling ends between its pieces (what it
    sampled so far may be kept, as on a deadline)."""


class OutOfBounds(ValueError):
    """An input asks for more work than the service allows (HTTP 422, FastAPI's error shape)."""

    def __init__(self, loc: tuple[str, ...], message: str, value: Any) -> None:
        super().__init__(message)
        self.loc, self.message, self.value = loc, message, value

    def errors(self) -> list[dict[str, Any]]:
        return [
            {"type": "value_error", "loc": list(self.loc), "msg": self.message, "input": self.value}
        ]


@contextmanager
def deadline(seconds: float) -> Iterator[None]:
    """Work in this context (and the threads its requests hand work to) ends by now + seconds."""
    token = _deadline.set((time.monotonic() + seconds, seconds))
    try:
        yield
    finally:
        _deadline.reset(token)


@contextmanager
def until(stopping: threading.Event) -> Iterator[None]:
    """Work in this context ends at its next check() once `stopping` is set: a server stopped
    while its worker samples the fleet's risk (~10 s) stops at once."""
    token = _stopping.set(stopping)
    try:
        yield
    finally:
        _stopping.reset(token)


def timed_out_message(seconds: float) -> str:
    return f"the request took longer than {seconds:g} s (request_timeout_seconds)"


def check() -> None:
    """Raise DeadlineExceeded when the current deadline has passed (no deadline: never), Stopped
    when the worker thread doing this work is stopping."""
    stopping = _stopping.get()
    if stopping is not None and stopping.is_set():
        raise Stopped("the worker is stopping")
    current = _deadline.get()
    if current is not None and time.monotonic() > current[0]:
        raise DeadlineExceeded(timed_out_message(current[1]))


def as_of_window(settings: Settings) -> tuple[date, date]:
    """The as-of dates a request may ask for: from the earliest record date to the horizon's
    reach after today."""
    return settings.earliest_record_date, settings.today() + timedelta(
        days=settings.max_horizon_days
    )


def bounded_as_of(as_of: date | None, settings: Settings) -> date:
    """The as-of date of a request (default today); raises OutOfBounds outside as_of_window."""
    if as_of is None:
        return settings.today()
    first, last = as_of_window(settings)
    if not first <= as_of <= last:
        raise OutOfBounds(
            ("query", "as_of"),
            f"must lie in [{first}, {last}]: from FLEETPINN_EARLIEST_RECORD_DATE to today + "
            f"FLEETPINN_MAX_HORIZON_DAYS ({settings.max_horizon_days} days)",
            as_of.isoformat(),
        )
    return as_of


def max_sampled_flights(settings: Settings) -> int:
    """The most future flights one tail's draw may hold: its forecast_samples lanes then fill
    max_sampling_bytes."""
    return max(
        1, settings.max_sampling_bytes // (_BYTES_PER_LANE_FLIGHT * settings.forecast_samples)
    )


def within_span(flights: int, settings: Settings) -> bool:
    """Whether one tail's sampled future of `flights` flights per draw is within the budget:
    what a request would be refused (check_span) is never sampled ahead either."""
    return flights <= max_sampled_flights(settings)


def check_span(
    flights: int, lead_days: int, horizon_days: int, rate: float, settings: Settings
) -> None:
    """Raise OutOfBounds when one tail's sampled future (flights per draw) exceeds the budget."""
    limit = max_sampled_flights(settings)
    if not within_span(flights, settings):
        raise OutOfBounds(
            ("query", "as_of"),
            f"the forecast would sample {flights} future flights per draw ({lead_days} days from "
            f"the tail's last flight to as_of, then horizon_days {horizon_days}, at "
            f"{rate:.3g} flights a day), at most {limit} (FLEETPINN_MAX_SAMPLING_BYTES): ask "
            "for an earlier as_of or a shorter horizon",
            flights,
        )


def tails_per_march(flights: int, settings: Settings) -> int:
    """How many tails of up to `flights` future flights each one call of the sampler may take
    within max_sampling_bytes (at least one).  Its marches hold min(samples x tails,
    max(LANES_PER_MARCH, tails)) lanes (model.prognosis.sample_groups): a few samples of every
    tail once the tails fill a march, else all samples of a few tails.  In a worker thread
    (until()) at most STOPPABLE_TAILS, so that it stops within a piece (the demo fleet's 300
    tails in one piece held a server's stop for 10 s); a tail's draws do not depend on the
    tails sampled with it, so the pieces change no number."""
    lanes = settings.max_sampling_bytes // (_BYTES_PER_LANE_FLIGHT * max(flights, 1))
    tails = lanes if lanes >= LANES_PER_MARCH else max(1, lanes // settings.forecast_samples)
    return tails if _stopping.get() is None else min(tails, STOPPABLE_TAILS)
