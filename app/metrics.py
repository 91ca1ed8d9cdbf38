"""Prometheus metrics (prometheus-client): what this process measured, and the database's state
read when /metrics is scraped.

Process metrics: request latency per route template (app.middleware), rows ingested, retrain
duration and outcome, jobs finished (app.worker).  Each process counts its own: an API process
serves them at /metrics, a `fleetpinn worker --metrics-port P` process on its own port.  The
database state (active model version, jobs by status) is the same for every process, so it is
read at scrape time instead of being remembered.
"""

from __future__ import annotations

from prometheus_client import (
    CONTENT_TYPE_LATEST,
    REGISTRY,
    CollectorRegistry,
    Counter,
    Gauge,
    Histogram,
    generate_latest,
)

CONTENT_TYPE = CONTENT_TYPE_LATEST

REQUEST_SECONDS = Histogram(
    "fleetpinn_http_request_duration_seconds",
    "HTTP request latency by method and route template (unmatched paths: route 'unmatched').",
    ["method", "route"],
    buckets=(0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0),
)
REQUESTS = Counter(
    "fleetpinn_http_requests",
    "HTTP requests by method, route template and status code.",
    ["method", "route", "status"],
)
INGEST_ROWS = Counter(
    "fleetpinn_ingest_rows",
    "Rows of flights or inspections received, by outcome (inserted, duplicate).",
    ["kind", "outcome"],
)
INSPECTIONS_FLAGGED = Counter(
    "fleetpinn_inspections_flagged",
    "Inspections stored with a finding far from their tail's forecast (app.services.forecasts.assessment).",
)
RETRAIN_SECONDS = Histogram(
    "fleetpinn_retrain_duration_seconds",
    "Retrain jobs by outcome: activated, refused (by the promotion gate), candidate (stored "
    "without activation as asked), failed, cancelled.",
    ["outcome"],
    buckets=(1, 5, 10, 30, 60, 120, 300, 600, 1200, 1800, 3600),
)
RISK_SAMPLED = Counter(
    "fleetpinn_risk_sampled_tails",
    "Tails whose risk over a horizon was sampled and stored (app.services.forecasts.risk.fill_risk): a "
    "day's first ranking samples the fleet once, however many rankings ask at once.",
)
JOBS_FINISHED = Counter(
    "fleetpinn_jobs_finished", "Jobs run to an end by this process.", ["kind", "status"]
)


def exposition(active_version: int | None, jobs_by_status: dict[str, int]) -> bytes:
    """This process's metrics followed by the database's state in the text format."""
    state = CollectorRegistry()
    Gauge(
        "fleetpinn_active_model_version",
        "The model version serving forecasts (0: none).",
        registry=state,
    ).set(active_version or 0)
    jobs = Gauge("fleetpinn_jobs", "Jobs in the database by status.", ["status"], registry=state)
    for status, count in jobs_by_status.items():
        jobs.labels(status=status).set(count)
    return generate_latest(REGISTRY) + generate_latest(state)
