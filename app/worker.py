"""Job runner: claims queued jobs from the jobs table, runs them, records progress and outcome;
beside it, a thread that keeps the forecast cache ahead of the requests.

Runs inside the API process (started in the lifespan) or as `fleetpinn worker` processes, the
layout to serve with: there a retrain shares no GIL with the requests and runs at a lower
priority.  Several may run against one database (see app.services.jobs.queue.claim_next).
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time
from collections.abc import Callable
from datetime import date
from typing import Any, Protocol

from sqlalchemy.orm import Session, sessionmaker

from app import budget, metrics
from app.config import Settings
from app.services import models as model_service
from app.services.dates import days_ahead
from app.services.forecasts import cache_advance
from app.services.jobs import batch as batch_service
from app.services.jobs import queue as jobs
from app.services.jobs import retrain as retrain_service
from app.services.ranking import order as ranking_service
from app.services.records import history
from app.thread_priority import lower_this_thread
from model.runtime import configure_threads

log = logging.getLogger("fleetpinn.worker")

_PROGRESS_EVERY_S = 0.5


class JobCancelled(Exception):
    """Raised inside a job when its cancellation was requested."""


class ProgressFn(Protocol):
    """Reports a job's progress (0..1) and, on a change, its stage in words."""

    def __call__(self, progress: float, stage: str | None = None) -> None: ...


Runner = Callable[[Session, str, dict[str, Any], Settings, ProgressFn], dict[str, Any]]


def _retrain(
    session: Session,
    job_id: str,
    params: dict[str, Any],
    settings: Settings,
    progress: ProgressFn,
) -> dict[str, Any]:
    return retrain_service.run_retrain(
        session, job_id=job_id, params=params, settings=settings, progress=progress
    )


def _forecast_batch(
    session: Session,
    job_id: str,
    params: dict[str, Any],
    settings: Settings,
    progress: ProgressFn,
) -> dict[str, Any]:
    return batch_service.run_batch(
        session,
        version=params.get("model_version"),
        settings=settings,
        progress=progress,
        refresh=bool(params.get("refresh", False)),
    )


RUNNERS: dict[str, Runner] = {"retrain": _retrain, "forecast-batch": _forecast_batch}


class _Progress:
    """Throttled progress reports in their own short transactions (a new stage is reported at
    once); raises JobCancelled on request."""

    def __init__(self, factory: sessionmaker[Session], job_id: str) -> None:
        self.factory, self.job_id = factory, job_id
        self.last_report = 0.0
        self.stage: str | None = None

    def __call__(self, progress: float, stage: str | None = None) -> None:
        now = time.monotonic()
        new_stage = stage is not None and stage != self.stage
        if not new_stage and now - self.last_report < _PROGRESS_EVERY_S:
            return
        self.last_report = now
        self.stage = stage or self.stage
        with self.factory() as session:
            cancelled = jobs.report_progress(session, self.job_id, progress, stage)
        if cancelled:
            raise JobCancelled(self.job_id)


class _Heartbeat:
    """Marks a job alive every `every_s` seconds from a side thread while the job runs."""

    def __init__(self, factory: sessionmaker[Session], job_id: str, every_s: float) -> None:
        self.factory, self.job_id, self.every_s = factory, job_id, every_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._beat, name="fleetpinn-heartbeat", daemon=True)

    def _beat(self) -> None:
        while not self._stop.wait(self.every_s):
            try:
                with self.factory() as session:
                    jobs.heartbeat(session, self.job_id)
            except Exception:  # a missed beat is harmless; the next one retries
                log.warning("heartbeat of job %s failed", self.job_id, exc_info=True)

    def __enter__(self) -> _Heartbeat:
        self._thread.start()
        return self

    def __exit__(self, *_: object) -> None:
        self._stop.set()
        self._thread.join()


def run_job(factory: sessionmaker[Session], job_id: str, settings: Settings) -> str:
    """Run one claimed job to its end; returns its final status.  Logs a line when it starts
    and one when it ends (status, seconds, outcome), and counts it in app.metrics."""
    with factory() as session:
        job = jobs.get_job(session, job_id)
        kind, params, attempt = job.kind, dict(job.params), job.attempts
        requester = jobs.requested_by(session, job)
    fields = {
        "job_id": job_id,
        "kind": kind,
        "attempt": attempt,
        "requested_by": None if requester is None else requester.name,
        # the request that queued it, to follow one story through the logs
        "request_id": None if requester is None else requester.request_id,
    }
    log.info("job %s (%s) started, attempt %d", job_id, kind, attempt, extra=fields)
    started = time.monotonic()
    progress = _Progress(factory, job_id)
    result: dict[str, Any] | None = None
    error: str | None = None
    beating = _Heartbeat(factory, job_id, settings.job_stale_seconds / 10)
    try:
        runner = RUNNERS[kind]
        with beating, factory() as session:
            result = runner(session, job_id, params, settings, progress)
    except JobCancelled:
        status, error = "cancelled", "cancelled on request"
    except Exception as exc:  # a job's failure is its record, never the worker's end
        log.exception("job %s (%s) failed", job_id, kind)
        status, error = "failed", f"{type(exc).__name__}: {exc}"
    else:
        status = "succeeded"
    with factory() as session:
        jobs.finish(session, job_id, status, result=result, error=error)
    seconds = time.monotonic() - started
    outcome = (result or {}).get("outcome", status) if status == "succeeded" else status
    metrics.JOBS_FINISHED.labels(kind, status).inc()
    if kind == "retrain":
        metrics.RETRAIN_SECONDS.labels(outcome).observe(seconds)
    log.info(
        "job %s (%s) %s after %.1f s",
        job_id,
        kind,
        status,
        seconds,
        extra={
            **fields,
            "status": status,
            "outcome": outcome,
            "duration_s": round(seconds, 3),
            "model_version": (result or {}).get("model_version"),
            "reason": (result or {}).get("reason"),
            "error": error,
        },
    )
    return status


def run_pending(factory: sessionmaker[Session], settings: Settings, worker: str) -> int:
    """Run queued jobs until none is left; returns how many ran.  The flights a retrain kept
    for the next job (app.services.records.history) are dropped once none is left."""
    ran = 0
    while True:
        with factory() as session:
            job_id = jobs.claim_next(session, worker, stale_after_s=settings.job_stale_seconds)
        if job_id is None:
            history.forget_flights()
            return ran
        run_job(factory, job_id, settings)
        ran += 1


class Worker:
    """Two daemon threads: one runs the queued jobs, one keeps the forecast cache ahead of the
    requests (the bands an older release's ingests left pending, the next day's risk that
    ingests leave, and each day's risk of the fleet: app.services.forecasts.cache_advance.fill_pending,
    ranking.warm).  `nice`: how much lower the job thread runs than the rest of the process
    (Linux threads each have their own), so a retrain takes the CPU that requests and the
    cache leave; the cache thread runs half as much lower (_keep_cache)."""

    def __init__(
        self, factory: sessionmaker[Session], settings: Settings, name: str, *, nice: int = 0
    ) -> None:
        self.factory, self.settings, self.nice = factory, settings, nice
        self.name = f"{socket.gethostname()}:{os.getpid()}:{name}"
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        # (today, each location's active version) warmed last
        self._warmed: tuple[date, tuple[tuple[int, int], ...]] | None = None

    def start(self) -> None:
        thread = threading.Thread(target=self.run_forever, name="fleetpinn-worker", daemon=True)
        self._threads.append(thread)
        thread.start()

    def stop(self, timeout: float = 10.0) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join(timeout)

    def run_forever(self) -> None:
        """Run jobs until stopped, the cache thread beside (started at this thread's priority,
        before it is lowered)."""
        configure_threads()  # shares the box with the API (model.runtime says why)
        cache = threading.Thread(target=self._keep_cache, name="fleetpinn-cache", daemon=True)
        self._threads.append(cache)
        cache.start()
        lower_this_thread(self.nice)
        while not self._stop.is_set():
            try:
                ran = run_pending(self.factory, self.settings, self.name)
            except Exception:  # the database may be briefly unreachable; keep polling
                log.exception("worker poll failed")
                ran = 0
            if not ran:
                self._stop.wait(self.settings.worker_poll_seconds)

    def _keep_cache(self) -> None:
        # Below the requests, above the jobs: what it samples after an ingest (tomorrow's risk,
        # ~0.2 s of CPU with four locations) is read by nobody before midnight, and at the
        # process's priority it took that CPU from the API's requests (benchmarks/RESULTS.md)
        lower_this_thread(self.nice // 2)
        with budget.until(self._stop):  # stop() ends its sampling between pieces
            while not self._stop.is_set():
                try:
                    with self.factory() as session:
                        sampled = cache_advance.fill_pending(session, self.settings)
                except budget.Stopped:
                    return
                except Exception:  # a row changed meanwhile, or the database is busy: retry
                    log.warning("sampling pending forecast bands failed", exc_info=True)
                    sampled = 0
                try:
                    self.warm_today()
                except budget.Stopped:
                    return
                if not sampled:
                    self._stop.wait(self.settings.worker_poll_seconds)

    def warm_today(self) -> None:
        """Store the fleet's risk as of today and tomorrow where missing (app.services.ranking.order.
        warm, dates.days_ahead): a ranking that had to sample a day's risk for the whole fleet
        would wait ~13 s, and each request behind it.  Today's once per day and set of active
        versions; tomorrow's on every call, for the tails ingested since (an ingest samples
        today's alone: app.services.forecasts.cache_advance), one fingerprint a version while none
        changed (rows a write dropped are left to their readers, as before)."""
        today, tomorrow = days_ahead(self.settings)
        try:
            with self.factory() as session:
                active = tuple(sorted(model_service.active_versions(session).items()))
                if not active:
                    return
                if self._warmed == (today, active):  # rows a write dropped: their readers'
                    ranking_service.warm(session, self.settings, tomorrow, fill=False)
                    return
                for day in (today, tomorrow):
                    ranking_service.warm(session, self.settings, day)
        except budget.Stopped:
            raise
        except budget.OutOfBounds as refused:  # what a ranking is refused: not retried today
            log.info("the ranking of %s is not warmed: %s", today, refused)
        except Exception:  # a tail changed meanwhile, or the database is busy: next poll retries
            log.warning("warming the ranking of %s failed", today, exc_info=True)
            return
        self._warmed = (today, active)
