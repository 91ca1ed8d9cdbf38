"""The promotion gate: a retrained candidate replaces the active version only if it predicts the
same held-out inspections about as well.

Both versions predict the measured inspections the retrain held out (model.evaluation's
|% error|, the same rows for both); the candidate passes when its mean error is at most
gate_max_error_pct and at most gate_max_error_increase_pct percentage points above the active
version's.  Without an active version only the first bound applies.  When fewer than three
tails are inspected nothing is held out, and both are compared on the training inspections
instead (evaluated_on "training": a weak check, but it still stops a fit that went wrong).  No
measured inspection at all: nothing to compare on, so the candidate passes only when no version
is active.  The active version may have been trained on some of the held-out tails (the split
moves as tails are inspected); that favours the version in service, the safe side.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from sqlalchemy.orm import Session

from app.config import Settings
from app.services import models as model_service
from model.evaluation import abs_percent_errors
from model.hybrid import CrackGrowthModel
from model.integrate import LoadHistory, Observations


@dataclass(frozen=True)
class Gate:
    """The gate's verdict with its evidence: each version's |% error| metrics (count, mean,
    median, max) on the same inspections, and the thresholds applied."""

    passed: bool
    reason: str
    evaluated_on: str
    candidate: dict[str, Any]
    active_version: int | None
    active: dict[str, Any] | None
    max_error_pct: float
    max_error_increase_pct: float

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def decide(
    candidate: dict[str, Any],
    active: dict[str, Any] | None,
    *,
    active_version: int | None,
    evaluated_on: str,
    max_error_pct: float,
    max_error_increase_pct: float,
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
        )

    if not candidate.get("count"):
        if active is None:
            return gate(True, "no measured inspection to compare on, and no version is active")
        return gate(False, "no measured inspection to compare on; the active version stays")
    error = candidate["mean_abs_pct_error"]
    on = f"{candidate['count']} {evaluated_on} inspections"
    if error > max_error_pct:
        also = (
            "" if active is None else f" (v{active_version}: {active['mean_abs_pct_error']:.3g} %)"
        )
        return gate(
            False,
            f"mean |error| {error:.3g} % on {on} exceeds the bound of {max_error_pct:g} %{also}",
        )
    if active is None:
        return gate(True, f"mean |error| {error:.3g} % on {on}; no version was active")
    bound = active["mean_abs_pct_error"] + max_error_increase_pct
    if error > bound:
        return gate(
            False,
            f"mean |error| {error:.3g} % on {on} is worse than v{active_version}'s "
            f"{active['mean_abs_pct_error']:.3g} % by more than {max_error_increase_pct:g} "
            "percentage points",
        )
    return gate(
        True,
        f"mean |error| {error:.3g} % on {on} against v{active_version}'s "
        f"{active['mean_abs_pct_error']:.3g} %",
    )


def evaluate(
    session: Session,
    candidate: CrackGrowthModel,
    loads: LoadHistory,
    observations: Observations,
    *,
    evaluated_on: str,
    settings: Settings,
) -> Gate:
    """Score the candidate and the active version on the same inspections and decide."""
    active_version = model_service.active_version_number(session)
    active = None
    if active_version is not None:
        active_model = model_service.load_model(session, active_version)
        active = abs_percent_errors(active_model, loads, observations)
    return decide(
        abs_percent_errors(candidate, loads, observations),
        active,
        active_version=active_version,
        evaluated_on=evaluated_on,
        max_error_pct=settings.gate_max_error_pct,
        max_error_increase_pct=settings.gate_max_error_increase_pct,
    )
