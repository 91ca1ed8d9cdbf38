"""The requests a valid OpenAPI schema cannot keep from a 422: what the fuzzer's
positive_data_acceptance check lets pass (tests/app/test_fuzz.py), and what
tests/app/test_schema_rules.py shows the server refuses while the schema takes it."""

from __future__ import annotations

# Refusals of schema-valid data for a rule JSON Schema cannot state: it cannot compare two values
# of one request, nor read an uploaded file's content.  Each rule is said in its field's
# description and answered 422 naming the field; positive_data_acceptance lets a 422 pass only
# where its reason holds one of its operation's phrases here, so any other refusal of
# schema-valid data still fails.
UNSTATABLE: dict[str, tuple[str, ...]] = {
    "PUT /locations/{name}": (
        # a crack case's dimensions against each other (app.crack_case_schema)
        "hole diameters",
        "radius over thickness_m",
        "shape_at_depth_m: an evolving shape",
        "crack_length_m, beta_values",
        # the critical crack above the initial one, a90 above a50, both given
        "must exceed initial_crack_m",
        "must exceed pod_a50_m",
        # a geometry table's lengths in order, one factor each
        "crack lengths must increase strictly",
        "one factor per crack length",
    ),
    "POST /aircraft/{tail}/flights": (
        # rainflow: a history of equal points holds no cycle (the schema states a point > 0,
        # which with two points apart makes a tensile cycle)
        "holds no cycle with a tensile maximum",
        # a cycle's minimum below its maximum
        "must be below max_stress_mpa",
        # a cycle's range above the plausible one where it is its max less its min, or a
        # history's rainflow cycle (a range sent is stated: CycleIn's maximum)
        "(FLEETPINN_MAX_STRESS_RANGE_MPA)",
        # one flight_id twice in a batch with other values (uniqueItems says whole items)
        "with different values",
        # a damage-equivalent range that underflows to 0 (cycles of 5e-324 MPa)
        "must be > 0, got 0",
    ),
    "PUT /aircraft/{tail}/locations": ("unknown location",),
    "POST /aircraft/{tail}/inspections": (
        "must be > pod_a50_m",
        # a location named as the schema allows but not in the catalogue: the database's state
        "unknown location",
        "with different values",
    ),
    # the network's weights, from its layers' widths multiplied
    "POST /models/retrain": ("the network would have",),
}
# Operations whose file's content the schema cannot state: any 422 naming the file (source).
CONTENT_CHECKED = {"POST /flights/upload"}


def refused_for_unstatable_rule(operation: str, status: int, body: object) -> bool:
    """Whether a 422 for schema-valid data names one of UNSTATABLE's rules of `operation` (or
    the uploaded file of a CONTENT_CHECKED one)."""
    if status != 422 or not isinstance(body, dict):
        return False
    if operation in CONTENT_CHECKED and body.get("source") not in (None, "body"):
        return True
    reason = str(body.get("reason") or "")
    return any(phrase in reason for phrase in UNSTATABLE.get(operation, ()))
