"""Issue 41's goal: a fleet whose location is defined by a crack case (a centre crack in a
finite-width panel, Feddersen's secant) is tracked as well as the same fleet given the
equivalent table.  A small fleet of model.fleet's generator with a secant geometry (its truth's
F = sqrt(sec(pi a / 2b)), b the half width) is inspected alike at two locations, one given by
`crack_case` and one by `geometry_table` (the truth tabulated at 64 points); both learn C and m
through their table, and their forecasts of every tail agree."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.local_server import wait_for_job
from model.fleet import FleetConfig, generate_fleet, inspect_at, true_geometry_factor
from model.physics import ParisLaw
from tests.app.conftest import AS_OF, SQLITE_ONLY

pytestmark = SQLITE_ONLY

# fast enough that two years take the fleet's cracks from 4 mm up the secant's rise (7-25 mm
# at the last inspection, some tails past a_crit by the last flight)
ALLOY = ParisLaw(c=6e-10, m=3.0, initial_crack_m=0.004, critical_crack_m=0.04)
HALF_WIDTH_M = 0.0612  # F rises 1.003 -> 1.39 from a0 to a_crit
COMMON = {"initial_crack_m": 0.004, "critical_crack_m": 0.04, "growth_law": {"law": "paris", "learn": True}}  # fmt: skip
CASE = {**COMMON, "crack_case": {"type": "centre_crack", "width_m": 2 * HALF_WIDTH_M, "method": "feddersen"}}  # fmt: skip


def _table() -> dict[str, list[float]]:
    a = np.geomspace(ALLOY.initial_crack_m, ALLOY.critical_crack_m, 64)
    return {
        "crack_length_m": a.tolist(),
        "factor": true_geometry_factor(a, ALLOY, "secant", HALF_WIDTH_M).tolist(),
    }


def test_a_crack_case_location_is_tracked_as_its_equivalent_table(client: TestClient) -> None:
    fleet = generate_fleet(
        FleetConfig(
            aircraft_per_mix=3,
            years=2,
            law=ALLOY,
            geometry="secant",
            discrepancy=HALF_WIDTH_M,
            growth_scatter=0.1,
            seed=5,
            start=f"{AS_OF.year - 2}-01-01T00:00:00Z",
        )
    )
    assert client.put("/locations/panel-case", json=CASE).status_code == 201
    assert client.put("/locations/panel-table", json={**COMMON, "geometry_table": _table()}).status_code == 201  # fmt: skip
    frame = fleet.flights_frame()
    for tail, rows in frame.groupby("tail", sort=False):
        assert client.put(f"/aircraft/{tail}").status_code == 201
        body = [
            {"flight_id": r.flight_id, "flown_at": r.flown_at.isoformat(),
             "stress_range_mpa": r.stress_range_mpa, "mission": r.mission}
            for r in rows.itertuples()
        ]  # fmt: skip
        assert client.post(f"/aircraft/{tail}/flights", json=body).status_code == 201
    per_year = fleet.config.flights_per_year
    inspected = np.arange(0, fleet.size, 2)
    sample = inspect_at(fleet, inspected, np.array([per_year // 2, per_year, 3 * per_year // 2]), noise_sd=0.02, seed=5)  # fmt: skip
    for row in fleet.inspections_frame(sample).itertuples():
        for location in ("panel-case", "panel-table"):
            body = {"inspection_id": f"{row.inspection_id}-{location}", "inspected_at": row.inspected_at.isoformat(),
                    "crack_length_m": row.crack_length_m, "location": location}  # fmt: skip
            assert client.post(f"/aircraft/{row.tail}/inspections", json=body).status_code == 201
    accepted = client.post("/models/retrain").json()
    assert set(accepted["jobs"]) == {"panel-case", "panel-table"}
    for job in accepted["jobs"].values():
        assert wait_for_job(client, job)["status"] == "succeeded"
    truth = fleet.final_crack_m
    errors: dict[str, list[float]] = {"panel-case": [], "panel-table": []}
    gaps: list[float] = []
    for i, tail in enumerate(fleet.tails):
        answers = {
            location: client.get(
                f"/aircraft/{tail}/locations/{location}/forecast", params={"horizon_days": 180}
            ).json()
            for location in errors
        }
        case, table = answers["panel-case"], answers["panel-table"]
        if truth[i] < ALLOY.critical_crack_m:
            gaps.append(abs(case["crack_length_m"] / table["crack_length_m"] - 1))
            assert case["crack_length_m"] == pytest.approx(table["crack_length_m"], rel=1e-3), tail
        assert case["prob_critical"] == pytest.approx(table["prob_critical"], abs=0.03), tail
        for quantile in ("p05", "p50", "p95"):
            a, b = case["crack_at_horizon"][quantile], table["crack_at_horizon"][quantile]
            assert (a is None) == (b is None) or min(a or 1, b or 1) > 0.95 * ALLOY.critical_crack_m, tail  # fmt: skip
            if a is not None and b is not None:
                assert a == pytest.approx(b, rel=0.02), (tail, quantile)
        for location, answer in answers.items():
            if truth[i] < ALLOY.critical_crack_m and answer["crack_length_m"] is not None:
                errors[location].append(abs(math.log(answer["crack_length_m"] / truth[i])))
    # tracked as well: the case's median error against the truth (measured 0.1055 for both)
    # within 1 % of the table's
    below = int((truth < ALLOY.critical_crack_m).sum())
    assert len(errors["panel-case"]) == len(errors["panel-table"]) == below >= fleet.size // 2
    case_error, table_error = (float(np.median(errors[k])) for k in ("panel-case", "panel-table"))
    # measured: 2.1e-5 (the case tabulated within 0.1 %, the truth at 64 points)
    assert max(gaps) < 1e-3
    assert case_error <= table_error + 0.01, (case_error, table_error)
