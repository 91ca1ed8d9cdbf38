"""A location given by a crack case (PUT/GET /locations): beta(a) computed from the case,
a_crit from the limit stress, 422s naming the dimension, and physics that reads the table."""

from __future__ import annotations

import math
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.local_server import wait_for_job
from app.services.forecasts.residual_now import residual_now
from app.services.records.location_cracks import crack_case_answer
from app.services.records.locations import StoredLocation, physics
from model.crack_cases.centre import CentreCrack
from model.crack_cases.edge import SingleEdgeCrack
from model.crack_cases.hole import CrackAtHole
from model.crack_cases.residual_strength import Toughness, critical_crack
from model.geometry import GeometryTable
from tests.app.conftest import START, add_tail, inspect

CENTRE = {"type": "centre_crack", "width_m": 0.3, "method": "feddersen"}
PANEL = {
    "description": "Fuselage skin panel between frames",
    "crack_case": CENTRE,
    "initial_crack_m": 0.002,
    "limit_stress_mpa": 150.0,
    "fracture_toughness_mpa_sqrt_m": 80.0,
    "yield_strength_mpa": 345.0,
}


def test_a_crack_case_location_answers_its_beta_and_critical_crack(client: TestClient) -> None:
    created = client.put("/locations/panel", json=PANEL)
    assert created.status_code == 201, created.text
    body = created.json()
    assert body["crack_case"] == CENTRE
    assert client.get("/locations/panel").json() == body
    case = CentreCrack(0.3, "feddersen")
    want = critical_crack(case, 150.0, Toughness(80.0, "given", 345.0), 0.002)
    # by hand: sec form at K = 80, S = 150; net-section yield only at 0.0848 m (bisection in tests/model/crack_cases/test_centre.py)
    assert body["critical_crack"]["criterion"] == "fracture"
    assert body["critical_crack"]["crack_length_m"] == pytest.approx(want.crack_length_m)
    assert body["critical_crack"]["toughness_kind"] == "given"
    a_crit = want.crack_length_m
    k_at_crit = 150.0 * math.sqrt(math.pi * a_crit / math.cos(math.pi * a_crit / 0.3))
    assert k_at_crit == pytest.approx(80.0, rel=1e-9)
    beta = body["crack_case_beta"]
    lengths, values = np.array(beta["crack_length_m"]), np.array(beta["beta"])
    assert lengths[0] == pytest.approx(0.002) and lengths[-1] == pytest.approx(a_crit)
    assert np.allclose(values, case.beta(lengths), rtol=1e-12)
    assert beta["max_relative_error"] < 1e-3 and beta["warning"] is None
    strength = np.array(beta["residual_strength_mpa"])
    assert strength[-1] == pytest.approx(150.0, rel=1e-9)  # at a_crit it carries the limit
    margin = body["critical_crack"]["margin_at_initial"]
    # at a0 the short crack's section yields first: 345 (0.3 - 0.004) / 0.3 MPa
    by_fracture = 80.0 / math.sqrt(math.pi * 0.002 / math.cos(math.pi * 0.002 / 0.3))
    at_a0 = min(by_fracture, 345.0 * (0.3 - 0.004) / 0.3)
    assert at_a0 < by_fracture
    assert body["critical_crack"]["residual_strength_at_initial_mpa"] == pytest.approx(at_a0)
    assert body["critical_crack"]["criterion_at_initial"] == "net_section_yield"
    assert margin == pytest.approx(at_a0 / 150.0 - 1, rel=1e-9)


def test_the_validity_warnings_state_lengths_in_mm_and_the_fields_stay_in_m(
    client: TestClient,
) -> None:
    """A structures engineer reads mm: the texts say where the range ends with the section's
    dimensions in mm, the numbers beside them stay SI.  An edge crack in W = 50 mm ends Tada's
    a/W = 0.8 at 40 mm, before its typed a_crit of 45 mm; a surface crack in t = 9.8 mm ends
    Newman-Raju's a/t = 0.8 at 7.84 mm, and its a_crit at a = t (neither criterion before)."""
    edge = {"crack_case": {"type": "edge_crack", "width_m": 0.05},
            "initial_crack_m": 0.001, "critical_crack_m": 0.045}  # fmt: skip
    body = client.put("/locations/strip", json=edge).json()
    beta = body["crack_case_beta"]
    assert beta["validity_limit_m"] == pytest.approx(0.04) and body["critical_crack"] is None
    assert beta["warning"] == (
        "the crack leaves the case's validity range at a = 40.00 mm (a/W = 0.8 (tada); "
        "W = 50.00 mm); beta is held at its value there up to a = 45.00 mm"
    )
    surface = {"crack_case": {"type": "surface_crack", "thickness_m": 0.0098, "width_m": 0.2,
                              "aspect_ratio": 0.8},
               "initial_crack_m": 0.001, "limit_stress_mpa": 120.0,
               "fracture_toughness_mpa_sqrt_m": 90.0, "yield_strength_mpa": 345.0}  # fmt: skip
    body = client.put("/locations/stringer", json=surface).json()
    critical = body["critical_crack"]
    assert critical["crack_length_m"] == pytest.approx(0.0098)
    assert critical["criterion"] == "extent"
    assert critical["warning"] == (
        "a_crit = 9.80 mm lies past the case's validity range, which ends at a = 7.84 mm "
        "(a/t = 0.8 (Newman-Raju); t = 9.80 mm, W = 200.00 mm)"
    )
    assert body["crack_case_beta"]["warning"].endswith("up to a = 9.80 mm")
    assert client.get("/locations/stringer").json()["critical_crack"] == critical


def test_physics_reads_the_cases_table_and_its_critical_crack(settings: Settings) -> None:
    stored = _stored(crack_case=CENTRE, initial_crack_m=0.002, limit_stress_mpa=150.0,
                     fracture_toughness_mpa_sqrt_m=100.0)  # fmt: skip
    law = physics(stored, settings).law
    assert law.geometry_table is not None
    want = critical_crack(
        CentreCrack(0.3, "feddersen"), 150.0, Toughness(100.0, "given", None), 0.002
    )
    assert law.critical_crack_m == pytest.approx(want.crack_length_m)
    assert law.geometry_factor == pytest.approx(
        float(CentreCrack(0.3, "feddersen").beta(np.array([0.002]))[0])
    )
    # a case without a limit stress: tabulated up to the typed a_crit, which it keeps
    typed = _stored(crack_case={"type": "through_crack_at_hole", "hole_diameter_m": 0.005},
                    critical_crack_m=0.03)  # fmt: skip
    law = physics(typed, settings).law
    assert law.critical_crack_m == 0.03
    assert law.geometry_table is not None
    hole = CrackAtHole(0.005, 1)
    for a in (0.006, 0.011, 0.027):
        assert law.geometry_table.value_at(a) == pytest.approx(
            float(hole.beta(np.array([a]))[0]), rel=1e-3
        )


def test_a_constant_factor_location_is_unchanged(client: TestClient, settings: Settings) -> None:
    entry = {"geometry_factor": 1.12, "critical_crack_m": 0.04, "initial_crack_m": 0.002}
    body = client.put("/locations/plain", json=entry).json()
    assert {k: body[k] for k in entry} == entry
    assert body["crack_case"] is None and body["crack_case_beta"] is None
    assert body["critical_crack"] is None and body["limit_stress_mpa"] is None
    law = physics(_stored(**entry), settings).law
    assert (law.geometry_factor, law.geometry_table, law.critical_crack_m) == (1.12, None, 0.04)


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ({"crack_case": {"type": "centre_crack"}}, "crack_case.width_m"),
        ({"crack_case": {"type": "centre_crack", "width_m": -0.3}}, "crack_case.width_m"),
        ({"crack_case": {"type": "oval_crack", "width_m": 0.3}}, "crack_case.type"),
        ({"crack_case": {**CENTRE, "depth_m": 0.01}}, "crack_case.depth_m"),
        (
            {
                "crack_case": {
                    "type": "surface_crack",
                    "thickness_m": 0.004,
                    "width_m": 0.1,
                    "aspect_ratio": 2.5,
                }
            },
            "crack_case.aspect_ratio",
        ),
        ({"geometry_factor": 1.1}, "crack_case"),
        ({"critical_crack_m": 0.04}, "limit_stress_mpa"),
        ({"crack_case": None}, "limit_stress_mpa"),
    ],
)
def test_a_bad_crack_case_is_refused_naming_the_dimension(
    client: TestClient, change: dict[str, object], named: str
) -> None:
    answer = client.put("/locations/bad", json={**PANEL, **change})
    assert answer.status_code == 422, answer.text
    assert named in answer.json()["detail"][0]["msg"]
    assert client.get("/locations/bad").status_code == 404


@pytest.mark.parametrize(
    ("change", "column"),
    [
        ({"limit_stress_mpa": 2000.0}, "limit_stress_mpa"),  # fails at a0 already
        # past 2a/W = 0.7 (Feddersen), with a typed a_crit
        (
            {"initial_crack_m": 0.12, "limit_stress_mpa": None, "critical_crack_m": 0.14},
            "initial_crack_m",
        ),
        ({"fracture_toughness_mpa_sqrt_m": None}, "fracture_toughness_mpa_sqrt_m"),
    ],
)
def test_a_case_that_cannot_be_used_is_refused(
    client: TestClient, change: dict[str, object], column: str
) -> None:
    answer = client.put("/locations/bad", json={**PANEL, **change})
    assert answer.status_code == 422, answer.text
    assert answer.json()["column"] == column
    assert client.get("/locations/bad").status_code == 404


def _stored(**values: object) -> StoredLocation:
    now = datetime.now(UTC)
    base: dict[str, object] = {
        "description": "", "stress_factor": 1.0, "stress_factor_by_mission": None,
        "geometry_factor": None, "geometry_table": None, "initial_crack_m": None,
        "critical_crack_m": None, "material": None, "growth_law": None,
        "inspection_method": None, "sizing_relative_sd": None, "pod_a50_m": None,
        "pod_a90_m": None,
    }  # fmt: skip
    return StoredLocation(id=99, name="x", created_at=now, updated_at=now, **{**base, **values})  # type: ignore[arg-type]


def test_without_its_own_toughness_a_location_takes_its_materials(client: TestClient) -> None:
    """2024-T3's row has K_IC 34 MPa sqrt(m) and no K_c or yield strength (none cited): the
    critical crack is by fracture at K_IC, net-section yield unchecked."""
    entry = {**PANEL, "material": "2024-T3", "fracture_toughness_mpa_sqrt_m": None,
             "yield_strength_mpa": None, "limit_stress_mpa": 100.0}  # fmt: skip
    body = client.put("/locations/own", json=entry).json()
    critical = body["critical_crack"]
    assert (critical["toughness_kind"], critical["toughness_mpa_sqrt_m"]) == ("K_IC", 34.0)
    assert critical["yield_crack_m"] is None and critical["yield_strength_mpa"] is None
    a = critical["crack_length_m"]
    assert 100.0 * math.sqrt(math.pi * a / math.cos(math.pi * a / 0.3)) == pytest.approx(34.0)


def test_walkers_gamma_below_zero_is_a_location_option(
    client: TestClient, settings: Settings
) -> None:
    """Null by default (the material's gamma for every R, as before); 0 ignores compression."""
    body = client.put("/locations/gusty", json={"gamma_below_zero": 0.0}).json()
    assert body["gamma_below_zero"] == 0.0
    assert physics(_stored(gamma_below_zero=0.0), settings).law.gamma_below_zero == 0.0
    assert physics(_stored(), settings).law.gamma_below_zero is None
    answer = client.put("/locations/bad", json={"gamma_below_zero": 1.5})
    assert answer.status_code == 422
    assert "gamma_below_zero" in answer.json()["detail"][0]["loc"]


def test_a_crack_case_location_retrains_and_forecasts_through_its_table(
    client: TestClient,
) -> None:
    """Retrained and forecast like any location: the march reads the case's table at every
    crack (the physics' Euler step, F(a) by the table) and stops at the computed a_crit."""
    for tail, stress in (("LOW", 100.0), ("HIGH", 150.0)):
        add_tail(client, tail, 40, stress=stress)
    inspect(client, "LOW", START + timedelta(days=10), 0.00501)
    stored = client.put("/locations/panel", json=PANEL).json()
    table = GeometryTable.of(
        stored["crack_case_beta"]["crack_length_m"], stored["crack_case_beta"]["beta"]
    )

    def euler(crack: float, stress: float, flights: int) -> float:
        for _ in range(flights):
            crack += 1.5e-11 * (table.value_at(crack) * stress * math.sqrt(math.pi * crack)) ** 3.8
        return crack

    panel_inspection = {
        "inspection_id": "P1",
        "inspected_at": (START + timedelta(days=10)).isoformat(),
        "crack_length_m": euler(0.002, 100.0, 40),
        "location": "panel",
    }
    assert client.post("/aircraft/LOW/inspections", json=panel_inspection).status_code == 201
    body = client.post("/models/retrain").json()
    for name, job in body["jobs"].items():
        assert wait_for_job(client, job)["status"] == "succeeded", name
    forecast = client.get("/aircraft/HIGH/locations/panel/forecast", params={"horizon_days": 30})
    assert forecast.status_code == 200, forecast.text
    answer = forecast.json()
    assert answer["critical_crack_m"] == pytest.approx(stored["critical_crack"]["crack_length_m"])
    assert answer["crack_length_m"] == pytest.approx(euler(0.002, 150.0, 40), rel=1e-9)
    # the residual strength at the crack now, by hand: Feddersen's secant at K = 80, net
    # section 345 (W - 2a) / W, the smaller governs; p95's crack is the conservative one
    residual = answer["residual_strength"]
    assert (residual["limit_stress_mpa"], residual["toughness_kind"]) == (150.0, "given")
    for quantile in ("p50", "p95"):
        crack = answer["crack_as_of"][quantile]
        at = residual[quantile]
        assert at["crack_length_m"] == pytest.approx(crack, rel=1e-12)
        by_fracture = 80.0 / math.sqrt(math.pi * crack / math.cos(math.pi * crack / 0.3))
        by_yield = 345.0 * (0.3 - 2 * crack) / 0.3
        assert at["residual_strength_mpa"] == pytest.approx(min(by_fracture, by_yield))
        assert at["criterion"] == ("fracture" if by_fracture < by_yield else "net_section_yield")
        assert at["margin"] == pytest.approx(min(by_fracture, by_yield) / 150.0 - 1)
    assert residual["p95"]["residual_strength_mpa"] <= residual["p50"]["residual_strength_mpa"]
    # the default location (constant F, no toughness) cannot compute it: absent, as before
    plain = client.get("/aircraft/HIGH/locations/default/forecast", params={"horizon_days": 30})
    assert "residual_strength" not in plain.json()


def test_the_residual_strength_now_by_hand(settings: Settings) -> None:
    """A table location with a material and a limit stress: fracture at the material's K_IC
    (2024-T3: 34 MPa sqrt(m), no yield strength); without a limit stress none (as before crack
    cases, though the material gives a toughness); a crack case past its extent carries
    nothing; a constant factor, or no toughness, cannot compute one."""
    table = {"crack_length_m": [0.001, 0.05], "factor": [1.1, 1.5]}
    located = _stored(geometry_table=table, material="2024-T3", limit_stress_mpa=120.0)
    now = residual_now(located, 0.01, 0.02, settings)
    assert now is not None and now.limit_stress_mpa == 120.0
    assert (now.toughness_kind, now.toughness_mpa_sqrt_m, now.yield_strength_mpa) == (
        "K_IC",
        34.0,
        None,
    )
    for at, crack in ((now.p50, 0.01), (now.p95, 0.02)):
        beta = 1.1 + 0.4 * (crack - 0.001) / 0.049
        want = 34.0 / (beta * math.sqrt(math.pi * crack))
        assert at.residual_strength_mpa == pytest.approx(want)
        assert at.criterion == "fracture"
        assert at.margin == pytest.approx(want / 120.0 - 1)
    unlimited = _stored(geometry_table=table, material="2024-T3")
    assert residual_now(unlimited, 0.01, 0.02, settings) is None
    # an edge crack in a 0.05 m strip: at a = 0.01 the net section (345 W / (W - a)) governs
    edge = _stored(crack_case={"type": "edge_crack", "width_m": 0.05}, limit_stress_mpa=100.0,
                   fracture_toughness_mpa_sqrt_m=80.0, yield_strength_mpa=345.0)  # fmt: skip
    now = residual_now(edge, 0.001, None, settings)
    assert now is not None
    beta = float(SingleEdgeCrack(0.05).beta(np.array([0.001]))[0])
    by_fracture = 80.0 / (beta * math.sqrt(math.pi * 0.001))
    assert now.p50.residual_strength_mpa == pytest.approx(min(by_fracture, 345.0 * 0.049 / 0.05))
    assert now.p50.margin == pytest.approx(now.p50.residual_strength_mpa / 100.0 - 1)
    # the p95 crack not finite (the march ran past a_crit): the section carries nothing
    assert (now.p95.residual_strength_mpa, now.p95.criterion, now.p95.margin) == (
        0.0,
        "extent",
        -1.0,
    )
    past = residual_now(edge, 0.06, 0.06, settings)
    assert past is not None and past.p50.criterion == "extent"
    constant = _stored(geometry_factor=1.12, material="2024-T3", limit_stress_mpa=120.0)
    assert residual_now(constant, 0.01, 0.02, settings) is None
    no_toughness = _stored(geometry_table=table, limit_stress_mpa=120.0)
    assert residual_now(no_toughness, 0.01, 0.02, settings) is None


def test_a_materials_files_k_c_and_yield_strength_set_a_crit(tmp_path: Path) -> None:
    """An operator's row with K_c 80 MPa sqrt(m) and yield 330 MPa (the shipped rows have
    neither): the centre crack's a_crit by hand at three limit stresses, fracture where
    S sqrt(pi a sec(pi a / W)) = K_c (bisection), net-section yield at a = W/2 (1 - S/sigma_y),
    whichever is smaller; the case gives no thickness, so K_c (not K_IC 34) applies."""
    table = tmp_path / "materials.csv"
    table.write_text(
        "name,c_m_per_cycle,m,gamma,k_ic_mpa_sqrt_m,source,k_c_mpa_sqrt_m,yield_strength_mpa\n"
        "TEST-SHEET,1.42e-11,3.59,0.68,34,an operator's coupon tests,80,330\n"
    )
    settings = Settings(materials_file=table)
    width = CENTRE["width_m"]
    assert isinstance(width, float)
    for stress, criterion in (
        (120.0, "fracture"),
        (200.0, "fracture"),
        (300.0, "net_section_yield"),
    ):
        entry = _stored(crack_case=CENTRE, material="TEST-SHEET", initial_crack_m=0.002,
                        limit_stress_mpa=stress)  # fmt: skip
        answer = crack_case_answer(entry, settings)
        assert answer is not None and answer.critical is not None and answer.toughness is not None
        assert (answer.toughness.kind, answer.toughness.fracture_toughness_mpa_sqrt_m) == (
            "K_c",
            80.0,
        )
        assert answer.toughness.yield_strength_mpa == 330.0
        low, high = 0.002, 0.5 * width * (1 - 1e-12)
        while high - low > 1e-13:
            middle = 0.5 * (low + high)
            k = stress * math.sqrt(math.pi * middle / math.cos(math.pi * middle / width))
            low, high = (middle, high) if k < 80.0 else (low, middle)
        net = 0.5 * width * (1 - stress / 330.0)
        assert answer.critical.criterion == criterion
        assert answer.critical.crack_length_m == pytest.approx(min(low, net), rel=1e-9)
