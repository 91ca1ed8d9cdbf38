"""Aircraft forecasts made before they are asked, by a thread of each API process that runs
below its request threads.

Each process keeps a tail's encoded forecast under its rows' stamps (app.services.
forecasts.forecast_answers), made by the first forecast of the tail that the process served: ~17 ms of
CPU with four locations, and after a version's activation or a process's start a 300-tail
fleet's 600 first forecasts (two processes) were most of the load benchmark's slowest
(benchmarks/RESULTS.md, session 15).  This thread reads every active version's row stamps
(one query a poll) and makes the default horizon's answer as of today for each tail whose rows
changed since it last made one: every tail at start, after an activation and on a new day; an
ingested tail after its ingest.  It makes them as a request does (forecast_answers.
made_ahead), so what it keeps is what the request would have made and kept, under the same
stamps.  A tail with a carried location's row missing is left to its readers: its fill (the
history marched under every draw, ~0.7 s) holds the lock that requests wait for, and a thread
below them must not hold it.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from datetime import date

from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from app import budget
from app.config import Settings
from app.errors import ConflictError, NotFoundError
from app.services.forecasts import forecast_answers
from app.services.forecasts.reports import ForecastReport
from app.tables import Aircraft, Forecast, ModelVersion
from app.thread_priority import lower_this_thread

log = logging.getLogger("fleetpinn.answers_ahead")

# (version, stamp) of each of a tail's rows of the active versions, in version order
Stamps = tuple[tuple[int, int | None], ...]

_ROWS = (
    select(Aircraft.id, Aircraft.tail, Forecast.model_version, Forecast.stamp)
    .join(Forecast, Forecast.aircraft_id == Aircraft.id)
    .join(
        ModelVersion,
        (ModelVersion.version == Forecast.model_version) & (ModelVersion.status == "active"),
    )
    .order_by(Aircraft.tail, Forecast.model_version)
)


class AnswersAhead:
    """One daemon thread, `nice` below the rest of the process, polling every
    settings.worker_poll_seconds.  It makes the answers of the first forecast_answers.KEPT // 2
    tails by name at most: half of what a process keeps, so that other answers keep room."""

    def __init__(
        self,
        factory: sessionmaker[Session],
        settings: Settings,
        encode: Callable[[ForecastReport], bytes],
        *,
        nice: int,
    ) -> None:
        self.factory, self.settings, self.encode, self.nice = factory, settings, encode, nice
        self._made: dict[int, Stamps] = {}  # aircraft id -> the stamps its answer was made at
        self._day: date | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = threading.Thread(
            target=self._run, name="fleetpinn-answers-ahead", daemon=True
        )
        self._thread.start()

    @property
    def native_id(self) -> int | None:
        """The thread's id in the kernel (None: not started)."""
        return None if self._thread is None else self._thread.native_id

    def stop(self, timeout: float = 10.0) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)

    def _run(self) -> None:
        lower_this_thread(self.nice)
        while not self._stop.is_set():
            try:
                self.make_changed()
            except Exception:  # the database busy or a tail changed meanwhile: the next poll
                log.warning("making forecasts ahead failed", exc_info=True)
            self._stop.wait(self.settings.worker_poll_seconds)

    def _make_one(self, tail: str, horizon: int, today: date) -> None:
        """The tail's answer made as a request makes it.  What a request would be refused
        (a 4xx: the tail deleted, a version retired, the sampling budget) is logged once, in a
        line; anything else with its traceback, the tail left to its readers."""
        try:
            with self.factory() as session:
                forecast_answers.made_ahead(
                    session,
                    tail,
                    horizon_days=horizon,
                    as_of=today,
                    settings=self.settings,
                    encode=self.encode,
                )
        except budget.Stopped:
            raise
        except (NotFoundError, ConflictError, ValueError) as refused:
            log.info("forecast of %s not made ahead: %s", tail, refused)
        except Exception:
            log.warning("making the forecast of %s ahead failed", tail, exc_info=True)

    def make_changed(self) -> int:
        """Make the answer of every tail whose rows changed since its answer was last made
        here (all of them on a new day); returns how many tails it went through."""
        today = self.settings.today()
        if today != self._day:
            self._made.clear()
            self._day = today
        with self.factory() as session:
            current = dict(list(_stamps(session).items())[: forecast_answers.KEPT // 2])
        todo = [
            (aircraft_id, tail, stamps)
            for aircraft_id, (tail, stamps) in current.items()
            if self._made.get(aircraft_id) != stamps
        ]
        horizon = min(self.settings.forecast_horizon_days, self.settings.max_horizon_days)
        for aircraft_id, tail, stamps in todo:
            if self._stop.is_set():
                break
            self._make_one(tail, horizon, today)
            # made, or refused: either way not tried again until its rows change (or the day
            # does), so an answer the service refuses (the sampling budget) is no hot loop
            self._made[aircraft_id] = stamps
        for gone in set(self._made) - set(current):
            del self._made[gone]
        return len(todo)


def _stamps(session: Session) -> dict[int, tuple[str, Stamps]]:
    """Each tail with a row of an active version: its tail and its rows' (version, stamp)."""
    out: dict[int, tuple[str, Stamps]] = {}
    for aircraft_id, tail, version, stamp in session.execute(_ROWS):
        _, before = out.get(aircraft_id, (tail, ()))
        out[aircraft_id] = (tail, (*before, (version, stamp)))
    return out
