"""Example values of the API's schemas (app.schemas, schemas_forecasts, schemas_ops), shown by /docs and used by "Try it out".

One consistent story: tail N100 of the demo fleet, inspected once, forecast under model v2.
Every example validates against its schema (tests/app/test_schema_examples.py).
"""

from __future__ import annotations

from typing import Any

from pydantic import ConfigDict

Example = dict[str, Any]


def examples(*values: Example, **config: Any) -> ConfigDict:
    """A model_config whose JSON schema carries these examples."""
    return ConfigDict(json_schema_extra={"examples": list(values)}, **config)  # type: ignore[typeddict-item]


HEALTH: Example = {"status": "ok"}
READY: Example = {
    "status": "ready",
    "database": True,
    "model_version": 2,
    "model_versions": {"default": 2, "wing-splice": 5},
}
AIRCRAFT_IN: Example = {"initial_crack_m": 0.006}
AIRCRAFT_OUT: Example = {
    "tail": "N100",
    "initial_crack_m": None,
    "created_at": "2026-01-05T08:00:00Z",
    "flight_count": 7300,
    "last_flown_at": "2029-12-31T18:00:00Z",
    "inspection_count": 1,
}
AIRCRAFT_PAGE: Example = {"items": [AIRCRAFT_OUT], "total": 300, "limit": 100, "offset": 0}
FLIGHT_IN: Example = {
    "flight_id": "F2025-000123",
    "flown_at": "2025-01-05T06:00:00Z",
    "stress_range_mpa": 82.5,
    "mission": "M2",
}
CYCLE_IN: Example = {"stress_range_mpa": 95.0, "load_ratio": -0.1}
CYCLE_EXTREMES_IN: Example = {"max_stress_mpa": 70.0, "min_stress_mpa": 42.0, "count": 3}
FLIGHT_CYCLES_IN: Example = {
    "flight_id": "F2025-000124",
    "flown_at": "2025-01-05T09:00:00Z",
    "cycles": [
        {"stress_range_mpa": 95.0, "load_ratio": -0.1},
        {"max_stress_mpa": 70.0, "min_stress_mpa": 42.0, "count": 3},
        {"stress_range_mpa": 20.0, "load_ratio": 0.6, "count": 0.5},
    ],
    "mission": "M2",
}
FLIGHT_HISTORY_IN: Example = {
    "flight_id": "F2025-000125",
    "flown_at": "2025-01-05T12:00:00Z",
    "stress_history_mpa": [-8.0, 62.0, 40.0, 88.0, 55.0, 70.0, -5.0],
}
INGEST_OUT: Example = {"inserted": 2, "duplicates": 0, "aircraft_created": 0}
INSPECTION_IN: Example = {
    "inspection_id": "I-2025-01",
    "inspected_at": "2025-01-05T00:00:00Z",
    "crack_length_m": 0.0068,
}
INSPECTION_NOT_FOUND_IN: Example = {
    "inspection_id": "I-2025-02",
    "inspected_at": "2025-06-01T00:00:00Z",
    "detected": False,
    "pod_a50_m": 0.001,
    "pod_a90_m": 0.0025,
}
INSPECTION_REPAIR_IN: Example = {
    "inspection_id": "I-2026-01",
    "inspected_at": "2026-02-10T00:00:00Z",
    "crack_length_m": 0.021,
    "repaired": True,
    "crack_after_repair_m": 0.001,
}
INSPECTION_OUT: Example = {
    "inspection_id": "I-2025-01",
    "inspected_at": "2025-01-05T00:00:00Z",
    "crack_length_m": 0.0068,
    "detected": True,
    "detection_threshold_m": None,
    "pod_a50_m": None,
    "pod_a90_m": None,
    "repaired": False,
    "crack_after_repair_m": None,
    "forecast_crack_m": 0.0066,
    "forecast_z": 0.59,
    "flagged": False,
    "recorded_by": "line-maintenance",
}
ASSESSMENT_OUT: Example = {
    "inspection_id": "I-2025-01",
    "forecast_crack_m": 0.0066,
    "forecast_z": 0.59,
    "flagged": False,
}
INSPECTION_INGEST_OUT: Example = {
    "inserted": 1,
    "duplicates": 0,
    "aircraft_created": 0,
    "assessments": [ASSESSMENT_OUT],
}
INSPECTION_PATCH: Example = {"crack_length_m": 0.0066}
FLIGHT_PATCH: Example = {"stress_range_mpa": 85.0}
FLIGHT_OUT: Example = {
    "flight_id": "F2025-000123",
    "flown_at": "2025-01-05T06:00:00Z",
    "stress_range_mpa": 82.5,
    "mission": "M2",
    "recorded_by": "ops-upload",
}
AUDIT_EVENT_OUT: Example = {
    "id": 412,
    "at": "2026-03-02T10:15:00Z",
    "actor": "line-maintenance",
    "role": "write",
    "action": "inspection.correct",
    "subject": "N100/I-2025-01",
    "request_id": "6c1f0f1d2a7e4d0b9a0c3e5f7a9b1c2d",
    "detail": {"before": {"inspection_id": "I-2025-01", "crack_length_m": 0.068}},
}
AUDIT_PAGE: Example = {"items": [AUDIT_EVENT_OUT], "total": 1, "limit": 50, "offset": 0}
RECORD_ERROR: Example = {
    "detail": "flights.csv row 12, column stress_range_mpa: must be > 0, got -3",
    "source": "flights.csv",
    "row": 12,
    "column": "stress_range_mpa",
    "reason": "must be > 0, got -3",
}
INVALID_REQUEST: Example = {
    "detail": [
        {
            "type": "missing",
            "loc": ["body", 0, "flown_at"],
            "msg": "Field required",
            "input": {"flight_id": "F0001", "stress_range_mpa": 120.0},
        }
    ],
    "row": 1,
    "column": "flown_at",
    "reason": "Field required",
}
ERROR: Example = {"detail": "unknown tail 'N999'"}
RETRAIN_IN: Example = {"activate": True, "kernel": "residual", "lbfgs_iterations": 60}
JOB_ACCEPTED: Example = {"job_id": "5f0c3c1e9a2b4d6f8e1a2b3c4d5e6f70", "status": "queued"}
_METRICS: Example = {
    "train": {
        "count": 12,
        "mean_abs_pct_error": 0.01,
        "median_abs_pct_error": 0.01,
        "max_abs_pct_error": 0.03,
    },
    "validation": {
        "count": 3,
        "mean_abs_pct_error": 0.02,
        "median_abs_pct_error": 0.02,
        "max_abs_pct_error": 0.04,
    },
}
GATE_OUT: Example = {
    "passed": True,
    "reason": "mean |error| 0.02 % on 3 validation inspections against v1's 0.9 %",
    "evaluated_on": "validation",
    "candidate": _METRICS["validation"],
    "active_version": 1,
    "active": {
        "count": 3,
        "mean_abs_pct_error": 0.9,
        "median_abs_pct_error": 0.8,
        "max_abs_pct_error": 1.4,
    },
    "max_error_pct": 50.0,
    "max_error_increase_pct": 1.0,
    "max_error_increase_ratio": 0.25,
}
JOB_OUT: Example = {
    "job_id": "5f0c3c1e9a2b4d6f8e1a2b3c4d5e6f70",
    "kind": "retrain",
    "status": "succeeded",
    "progress": 1.0,
    "stage": "done",
    "params": {"kernel": "residual"},
    "model_version": 2,
    "outcome": "activated",
    "outcome_reason": GATE_OUT["reason"],
    "metrics": _METRICS,
    "result": {
        "model_version": 2,
        "activated": True,
        "outcome": "activated",
        "reason": GATE_OUT["reason"],
        "metrics": {**_METRICS, "gate": GATE_OUT},
    },
    "error": None,
    "requested_by": "ops-admin",
    "created_at": "2026-03-01T09:00:00Z",
    "started_at": "2026-03-01T09:00:01Z",
    "finished_at": "2026-03-01T09:02:41Z",
}
MODEL_VERSION_OUT: Example = {
    "version": 2,
    "status": "active",
    "created_at": "2026-03-01T09:02:40Z",
    "activated_at": "2026-03-01T09:02:41Z",
    "spec": {"kernel": "residual", "hidden": [[5, "tanh"], [5, "tanh"]]},
    "training": {"optimizer": "lbfgs", "aircraft": 12, "observations": 12},
    "metrics": {**_METRICS, "gate": GATE_OUT},
    "gate": GATE_OUT,
    "job_id": "5f0c3c1e9a2b4d6f8e1a2b3c4d5e6f70",
}
_ORIGIN = "2029-12-31T18:00:00Z"
TRAJECTORY_POINT: Example = {
    "date": _ORIGIN,
    "flights": 7300,
    "crack_length_m": 0.0312,
    "p05": 0.0309,
    "p50": 0.0312,
    "p95": 0.0316,
}
_TRAJECTORY_END: Example = {
    "date": "2030-12-31T18:00:00Z",
    "flights": 8760,
    "crack_length_m": 0.0398,
    "p05": 0.0389,
    "p50": 0.0398,
    "p95": 0.0412,
}
CRACK_BAND: Example = {"p05": 0.0309, "p50": 0.0312, "p95": 0.0316}
_AS_OF = "2030-03-14T00:00:00Z"
CRACK_AT: Example = {
    "date": "2030-03-14T18:00:00Z",
    "flights": 8592,
    "crack_length_m": 0.0349,
    "p05": 0.0344,
    "p50": 0.0349,
    "p95": 0.0357,
}
_CRACK_AT_HORIZON: Example = {
    "date": "2031-03-14T18:00:00Z",
    "flights": 10052,
    "crack_length_m": 0.0451,
    "p05": 0.0437,
    "p50": 0.0451,
    "p95": 0.0475,
}
FLIGHTS_QUANTILES: Example = {"p05": 2410, "p50": 2630, "p95": None}
DATE_QUANTILES: Example = {
    "p05": "2031-08-24T06:00:00Z",
    "p50": "2031-10-17T12:00:00Z",
    "p95": None,
}
MISSION_SHARE_IN: Example = {"stress_range_mpa": 90.0, "share": 0.7}
PLANNED_UTILIZATION_IN: Example = {
    "flights_per_day": 4.0,
    "missions": [MISSION_SHARE_IN, {"stress_range_mpa": 120.0, "share": 0.3}],
}
FORECAST_IN: Example = {"horizon_days": 365, "planned": PLANNED_UTILIZATION_IN}
GROWTH_OUT: Example = {
    "factor_p05": 0.93,
    "factor_p50": 1.08,
    "factor_p95": 1.24,
    "fleet_growth_sd": 0.24,
    "sizing_relative_sd": 0.041,
    "inspection_ids": ["I-2023-06", "I-2025-01"],
}
DATA_AGE_OUT: Example = {
    "last_flown_at": _ORIGIN,
    "last_inspected_at": "2025-01-05T00:00:00Z",
    "days_since_last_flight": 73,
    "days_since_last_inspection": 1894,
    "stale": True,
}
FORECAST_OUT: Example = {
    "tail": "N100",
    "model_version": 2,
    "origin": _ORIGIN,
    "last_flown_at": _ORIGIN,
    "as_of": _AS_OF,
    "flights_flown": 7300,
    "crack_length_m": 0.0312,
    "crack_length_band": CRACK_BAND,
    "crack_as_of": CRACK_AT,
    "crack_at_horizon": _CRACK_AT_HORIZON,
    "critical_crack_m": 0.05,
    "flights_per_day": 4.0,
    "horizon_days": 365,
    "samples": 200,
    "model_uncertainty": True,
    "planned": False,
    "trajectory": [TRAJECTORY_POINT, _TRAJECTORY_END],
    "flights_to_critical": 2630,
    "critical_date": "2031-10-17T12:00:00Z",
    "prob_critical": 0.0,
    "flights_to_critical_quantiles": FLIGHTS_QUANTILES,
    "critical_date_quantiles": DATE_QUANTILES,
    "inspect_by": "2030-10-27T18:00:00Z",
    "inspect_rule": "half the p05 time to critical",
    "overdue": False,
    "past_critical": False,
    "past_critical_since": None,
    "data_age": DATA_AGE_OUT,
    "stale_after_days": 60,
    "growth": GROWTH_OUT,
}
LAST_INSPECTION: Example = {
    "inspection_id": "I-2025-01",
    "inspected_at": "2025-01-05T00:00:00Z",
    "detected": True,
    "crack_length_m": 0.0068,
    "repaired": False,
}
RANKING_ITEM: Example = {
    "rank": 1,
    "tail": "N100",
    "crack_length_m": 0.0312,
    "crack_length_band": CRACK_BAND,
    "critical_fraction": 0.624,
    "crack_as_of_band": {"p05": 0.0344, "p50": 0.0349, "p95": 0.0357},
    "crack_at_horizon_band": {"p05": 0.0437, "p50": 0.0451, "p95": 0.0475},
    "prob_critical": 0.0,
    "inspect_by": "2030-10-27T18:00:00Z",
    "overdue": False,
    "past_critical": False,
    "past_critical_since": None,
    "data_age": DATA_AGE_OUT,
    "flights_to_critical": 2630,
    "critical_date": "2031-10-17T12:00:00Z",
    "flights_to_critical_quantiles": FLIGHTS_QUANTILES,
    "critical_date_quantiles": DATE_QUANTILES,
    "last_inspection": LAST_INSPECTION,
    "flagged_inspection_ids": [],
    "flights_flown": 7300,
    "origin": _ORIGIN,
    "flights_per_day": 4.0,
}
RANKING_OUT: Example = {
    "model_version": 2,
    "critical_crack_m": 0.05,
    "horizon_days": 365,
    "as_of": _AS_OF,
    "by": "risk",
    "total": 300,
    "stale_after_days": 60,
    "items": [RANKING_ITEM],
}
FORECAST_BATCH_IN: Example = {"model_version": 2, "refresh": False}
