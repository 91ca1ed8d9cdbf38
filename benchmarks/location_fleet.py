"""The hidden fleet of benchmarks/locations.py: four locations of one recorded fleet, each with
its truth (local loads, physics, growth draw and a discrepancy its catalogue entry does not
know) and its inspection rounds; optionally a part whose F rises towards an edge, given to the
catalogue as a geometry table."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from app.config import Settings
from app.services.records import locations
from model.fleet import DISCREPANCY_20PCT, simulate_cracks, true_geometry_factor
from model.physics import ParisLaw

YEARS_INSPECTED = (2, 4)
YEARS_RECORDED = 5  # flights uploaded; the fleet flies on for the forecast horizon
# --geometry-table: the part's F = F0 sqrt(sec(pi a / 2W)) (a crack towards an edge), W this;
# tabulated for the catalogue at TABLE_POINTS cracks from a0 to a_crit (held beyond)
TABLE_HALF_WIDTH_M = 0.06
TABLE_POINTS = 8
# sd of the tails' log growth factors at every location (growth_draws)
GROWTH_SCATTER = 0.25


@dataclass(frozen=True)
class Place:
    """A location of the hidden fleet: its catalogue entry and the truth it does not say."""

    name: str
    entry: dict[str, Any]  # PUT /locations body (the default location: none)
    discrepancy: float  # beta of the true F(a) = F (1 + beta (a - a0) / (a_crit - a0))
    sizing_sd: float  # sizing error of its inspection method (ln measured - ln true)
    seed: int
    edge: bool = False  # its part's F rises towards an edge (_edge_factor) in the truth


PLACES = (
    Place("default", {}, DISCREPANCY_20PCT, 0.04, 0),
    Place(
        "wing-splice",
        {
            "stress_factor": 1.08,
            "initial_crack_m": 0.004,
            "critical_crack_m": 0.04,
            "sizing_relative_sd": 0.05,
            "pod_a50_m": 0.0015,
            "pod_a90_m": 0.0025,
            "inspection_method": "eddy current",
        },
        0.3,
        0.05,
        1,
    ),
    Place(
        "lap-joint",
        {
            "stress_factor": 0.92,
            "stress_factor_by_mission": {"M3": 1.0},
            "initial_crack_m": 0.005,
            "critical_crack_m": 0.045,
            "sizing_relative_sd": 0.03,
            "inspection_method": "ultrasonic",
        },
        0.1,
        0.03,
        2,
    ),
    Place(
        "bulkhead",
        {
            "stress_factor": 1.0,
            "geometry_factor": 1.05,
            "initial_crack_m": 0.004,
            "critical_crack_m": 0.035,
            "sizing_relative_sd": 0.04,
            "inspection_method": "visual + eddy current",
        },
        0.2,
        0.04,
        3,
    ),
)


def _edge_factor(crack_length_m: np.ndarray, at_a0: float, a0: float) -> np.ndarray:
    """The --geometry-table part's true F: at_a0 at a0, rising as sqrt(sec(pi a / 2W))."""

    def secant(a: np.ndarray) -> np.ndarray:
        return true_geometry_factor(a, ParisLaw(), "secant", TABLE_HALF_WIDTH_M)

    return at_a0 * secant(crack_length_m) / secant(np.asarray([a0]))[0]


def with_table(place: Place, settings: Settings, *, in_catalogue: bool = True) -> Place:
    """place whose part's F rises towards an edge from its constant F (or the model's) at a0,
    given to its catalogue entry as a table (in_catalogue), else as that constant alone (the
    physics before tables: F held at its a0 value)."""
    entry, base = dict(place.entry), settings.law()
    a0 = entry.get("initial_crack_m", base.initial_crack_m)
    critical = entry.get("critical_crack_m", base.critical_crack_m)
    at_a0 = entry.pop("geometry_factor", base.geometry_factor)
    lengths = np.linspace(a0, critical, TABLE_POINTS)
    factors = _edge_factor(lengths, at_a0, a0)
    if in_catalogue:
        entry["geometry_table"] = {
            "crack_length_m": [float(a) for a in lengths],
            "factor": [round(float(f), 6) for f in factors],
        }
    else:
        entry["geometry_factor"] = at_a0
    return Place(place.name, entry, place.discrepancy, place.sizing_sd, place.seed, edge=True)


def with_known_discrepancy(place: Place, settings: Settings) -> Place:
    """place whose catalogue entry gives its true F(a) = F (1 + beta t) as a table (linear in a:
    exact at TABLE_POINTS points): its truth as before, its physics no longer missing the rise
    (a diagnosis: what the forecast errs by once the model-form error is gone)."""
    entry, base = dict(place.entry), settings.law()
    a0 = entry.get("initial_crack_m", base.initial_crack_m)
    critical = entry.get("critical_crack_m", base.critical_crack_m)
    constant = entry.pop("geometry_factor", base.geometry_factor)
    lengths = np.linspace(a0, critical, TABLE_POINTS)
    law = ParisLaw(initial_crack_m=a0, critical_crack_m=critical)
    factors = constant * true_geometry_factor(lengths, law, "linear", place.discrepancy)
    entry["geometry_table"] = {
        "crack_length_m": [float(a) for a in lengths],
        "factor": [float(f) for f in factors],
    }
    return Place(place.name, entry, place.discrepancy, place.sizing_sd, place.seed)


def growth_draws(place: Place, tails: int) -> np.ndarray:
    """(tails,) the location's true growth factors (its material scatter)."""
    return np.exp(GROWTH_SCATTER * np.random.default_rng(100 + place.seed).standard_normal(tails))


def truth(
    fleet: Any, place: Place, settings: Settings, growth: np.ndarray | None = None
) -> np.ndarray:
    """(tails, flights + 1) true crack at the location: its local loads, its physics, its own
    growth scatter draw (material; growth (tails,) instead, where given) and a discrepancy the
    catalogue does not know; with a part towards an edge (Place.edge), the edge's F times that
    discrepancy."""
    local = local_stress(fleet.stress_range_mpa, fleet.mission, place)
    return march_truth(
        local, place, settings, growth_draws(place, fleet.size) if growth is None else growth
    )


def local_stress(stress_range_mpa: np.ndarray, mission: np.ndarray, place: Place) -> np.ndarray:
    """(tails, flights) the location's stress ranges from the recorded far-field ones and each
    flight's mission index, scaled as the service scales them (app.services.records.locations)."""
    entry = place.entry
    blank: dict[str, Any] = dict.fromkeys(locations.StoredLocation.__dataclass_fields__)
    location = locations.StoredLocation(
        **{
            **blank,
            "stress_factor": float(entry.get("stress_factor", 1.0)),
            "stress_factor_by_mission": entry.get("stress_factor_by_mission"),
        }
    )
    missions = pd.Series(np.asarray([f"M{m}" for m in range(4)])[mission.reshape(-1)])
    local = locations.scaled(stress_range_mpa.reshape(-1), missions, location)
    return local.reshape(stress_range_mpa.shape)


def base_law(place: Place, settings: Settings) -> ParisLaw:
    """The location's Paris law before its discrepancy and edge: the service's constants, its
    entry's F at a0, initial and critical crack."""
    entry, base = place.entry, settings.law()
    table = entry.get("geometry_table")
    return ParisLaw(
        c=base.c,
        m=base.m,
        geometry_factor=table["factor"][0]
        if table
        else entry.get("geometry_factor", base.geometry_factor),
        initial_crack_m=entry.get("initial_crack_m", base.initial_crack_m),
        critical_crack_m=entry.get("critical_crack_m", base.critical_crack_m),
    )


def march_truth(
    local: np.ndarray, place: Place, settings: Settings, growth: np.ndarray
) -> np.ndarray:
    """(rows, flights + 1) the true crack of each row of local stress ranges (rows, flights)
    at growth factor growth (rows,): the location's true law (truth's docstring)."""
    law = base_law(place, settings)
    if not place.edge:
        return simulate_cracks(local, law, place.discrepancy, growth)
    return _edge_truth(local, law, place.discrepancy, growth)


def _edge_truth(
    stress_mpa: np.ndarray, law: ParisLaw, discrepancy: float, growth: np.ndarray
) -> np.ndarray:
    """simulate_cracks's Euler march with F = the edge's (_edge_factor) x (1 + beta t)."""
    a0 = law.initial_crack_m
    crack = np.empty((stress_mpa.shape[0], stress_mpa.shape[1] + 1))
    crack[:, 0] = a0
    term = stress_mpa**law.m * growth[:, None]
    a = crack[:, 0].copy()
    for t in range(stress_mpa.shape[1]):
        factor = _edge_factor(a, law.geometry_factor, a0)
        factor = factor * true_geometry_factor(a, law, "linear", discrepancy)
        a = np.minimum(
            a + law.c * term[:, t] * (factor**2 * math.pi * a) ** (law.m / 2), law.held_crack_m
        )
        crack[:, t + 1] = a
    return crack


def inspection_id(location: str, year: int) -> str:
    """The id of the location's inspection round at the given year (inspections)."""
    return f"{location}-Y{year}"


def inspections(fleet: Any, truth: np.ndarray, place: Place, critical: float) -> pd.DataFrame:
    """Every tail at years 2 and 4, with the method's sizing error; cracks past a_crit left out."""
    fpy = fleet.config.flights_per_year
    rng = np.random.default_rng(10 + place.seed)
    rows = []
    for year in YEARS_INSPECTED:
        step = year * fpy
        true = truth[:, step]
        measured = true * np.exp(place.sizing_sd * rng.standard_normal(fleet.size))
        keep = true < critical
        at = fleet.flown_at[step - 1] + pd.Timedelta(minutes=30)
        rows.append(
            pd.DataFrame(
                {
                    "tail": np.asarray(fleet.tails)[keep],
                    "inspection_id": inspection_id(place.name, year),
                    "inspected_at": at,
                    "crack_length_m": measured[keep],
                    "location": place.name,
                }
            )
        )
    return pd.concat(rows, ignore_index=True)
