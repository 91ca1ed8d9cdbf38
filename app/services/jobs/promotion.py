"""The promotion gate: a retrained candidate replaces the active version only if it predicts the
same held-out inspections about as well.

Both versions predict the measured inspections the retrain held out (model.evaluation's
|% error|, the same rows for both, at the fleet's rate); the candidate passes when its mean
error exceeds the active version's by at most max(gate_max_error_increase_pct percentage
points, gate_max_error_increase_ratio x the active's error).  The relative part matters where
tails scatter: their held-out error at the fleet's rate is that scatter (a ln-sd of 0.25 gives
a mean of ~18 % at year 4 of the thesis fleet, over few inspections), so a fixed tolerance
would refuse on noise.  Without an active version, the candidate passes when its mean error is
at most gate_max_error_pct (a fit gone wrong).  When fewer than three
tails are inspected nothing is held out, and both are compared on the training inspections
instead (evaluated_on "training": a weak check, but it still stops a fit that went wrong).  No
measured inspection at all: nothing to compare on, so the candidate passes only when no version
is active.  The active version may have been trained on some of the held-out tails (the split
moves as tails are inspected); that favours the version in service, the safe side.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any

import numpy as np
import torch
from sqlalchemy.orm import Session

from app.config import Settings
from app.services import models as model_service
from app.tables import DEFAULT_LOCATION_ID
from model.integrate import LoadHistory, Observations
from model.posterior import LocationPosterior


@dataclass(frozen=True)
class Gate:
    """The gate's verdict with its evidence: each version's |% error| metrics (count, mean,
    median, max) on the same inspections, the thresholds applied and, for a refusal, the
    inspections that drive it (culprits: those the candidate predicts worst against the active
    version, most first; flagged: the flagged inspections it trained on, app.services.jobs.retrain)."""

    passed: bool
    reason: str
    evaluated_on: str
    candidate: dict[str, Any]
    active_version: int | None
    active: dict[str, Any] | None
    max_error_pct: float
    max_error_increase_pct: float
    max_error_increase_ratio: float
    culprits: list[dict[str, Any]] = field(default_factory=list)
    flagged: list[dict[str, Any]] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, stored: dict[str, Any]) -> Gate:
        """The verdict as to_dict stored it in a version's metrics["gate"] (a version stored
        before culprits or flagged were kept has none)."""
        known = {f.name for f in fields(cls)}
        return cls(**{key: value for key, value in stored.items() if key in known})


def decide(
    candidate: dict[str, Any],
    active: dict[str, Any] | None,
    *,
    active_version: int | None,
    evaluated_on: str,
    max_error_pct: float,
    max_error_increase_pct: float,
    max_error_increase_ratio: float,
) -> Gate:
    """The verdict on two metrics dicts of model.evaluation.abs_percent_errors (active None: no
    version is active)."""

    def gate(passed: bool, reason: str) -> Gate:
        return Gate(
            passed,
            reason,
            evaluated_on,
            candidate,
            active_version,
            active,
            max_error_pct,
            max_error_increase_pct,
            max_error_increase_ratio,
        )

    if not candidate.get("count"):
        if active is None:
            return gate(True, "no measured inspection to compare on, and no version is active")
        return gate(False, "no measured inspection to compare on; the active version stays")
    error = candidate["mean_abs_pct_error"]
    on = f"{candidate['count']} {evaluated_on} inspections"
    if active is None:
        if error > max_error_pct:
            return gate(
                False,
                f"mean |error| {error:.3g} % on {on} exceeds the bound of {max_error_pct:g} % "
                "for a first version",
            )
        return gate(True, f"mean |error| {error:.3g} % on {on}; no version was active")
    before = active["mean_abs_pct_error"]
    allowed = max(max_error_increase_pct, max_error_increase_ratio * before)
    if error > before + allowed:
        return gate(
            False,
            f"mean |error| {error:.3g} % on {on} is worse than v{active_version}'s "
            f"{before:.3g} % by more than {allowed:.3g} percentage points",
        )
    return gate(
        True, f"mean |error| {error:.3g} % on {on} against v{active_version}'s {before:.3g} %"
    )


# inspections a refusal names (Gate.culprits)
CULPRITS = 3


def evaluate(
    session: Session,
    candidate: LocationPosterior,
    loads: LoadHistory,
    observations: Observations,
    *,
    evaluated_on: str,
    settings: Settings,
    labels: Sequence[str] | None = None,
    location_id: int = DEFAULT_LOCATION_ID,
) -> Gate:
    """Score the candidate and the active version on the same inspections and decide; a
    refusal names the CULPRITS inspections (labels: one per observation, e.g. "N100/I-7") whose
    error grew most."""
    active_version = model_service.active_version_number(session, location_id)  # its location's
    active_model = None
    active = None
    if active_version is not None:
        active_model = model_service.load_posterior(session, active_version)
        active = active_model.errors(loads, observations)
    gate = decide(
        candidate.errors(loads, observations),
        active,
        active_version=active_version,
        evaluated_on=evaluated_on,
        max_error_pct=settings.gate_max_error_pct,
        max_error_increase_pct=settings.gate_max_error_increase_pct,
        max_error_increase_ratio=settings.gate_max_error_increase_ratio,
    )
    if gate.passed or labels is None:
        return gate
    return replace(gate, culprits=_culprits(candidate, active_model, loads, observations, labels))


def _culprits(
    candidate: LocationPosterior,
    active: LocationPosterior | None,
    loads: LoadHistory,
    observations: Observations,
    labels: Sequence[str],
) -> list[dict[str, Any]]:
    """The measured inspections whose |% error| the candidate raised most over the active
    version's (over none: the largest), with both errors."""
    measured = (
        torch.ones(len(labels), dtype=torch.bool)
        if observations.detected is None
        else observations.detected
    )
    index = torch.nonzero(measured).squeeze(1)
    if not len(index):
        return []
    kept = observations.subset(measured)
    measured_m = kept.crack_length_m.double()
    mine = (candidate.at(loads, kept) / measured_m - 1).abs().numpy() * 100
    theirs = None if active is None else (active.at(loads, kept) / measured_m - 1).abs() * 100
    worse = mine - (0.0 if theirs is None else theirs.numpy())
    out = []
    for k in np.argsort(-worse)[:CULPRITS]:
        out.append(
            {
                "inspection": labels[int(index[k])],
                "crack_length_m": float(measured_m[k]),
                "candidate_error_pct": round(float(mine[k]), 3),
                "active_error_pct": None if theirs is None else round(float(theirs[k]), 3),
            }
        )
    return out
