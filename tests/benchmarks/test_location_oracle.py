"""The locations benchmark's oracle (benchmarks/location_oracle.py): what it scores against must
itself be right, or every "against the oracle" in RESULTS.md reads wrong."""

from __future__ import annotations

import dataclasses

import pandas as pd

from app.config import Settings
from benchmarks import location_fleet as hidden
from benchmarks.location_oracle import oracle_rows
from model.fleet import DISCREPANCY_20PCT, FleetConfig, generate_fleet


def _bulkhead_oracle(sizing_sd: float, aircraft_per_mix: int) -> pd.DataFrame:
    """The oracle's rows for the bulkhead (its edge table, discrepancy 0.2) of a small fleet
    inspected at years 2 and 4 with the given sizing error, scored after year 5."""
    settings = Settings()
    bulkhead = next(p for p in hidden.PLACES if p.name == "bulkhead")
    place = dataclasses.replace(hidden.with_table(bulkhead, settings), sizing_sd=sizing_sd)
    fleet = generate_fleet(
        FleetConfig(
            aircraft_per_mix=aircraft_per_mix, years=6, discrepancy=DISCREPANCY_20PCT, seed=3
        )
    )
    fpy = fleet.config.flights_per_year
    truth = hidden.truth(fleet, place, settings)
    critical = place.entry["critical_crack_m"]
    measured = hidden.inspections(fleet, truth, place, critical)
    after = {hidden.inspection_id(place.name, y): y * fpy for y in hidden.YEARS_INSPECTED}
    rows = oracle_rows(fleet, place, settings, truth, measured, after, 5 * fpy, 6 * fpy - 1)
    assert len(rows) == int((truth[:, 5 * fpy] < critical).sum())
    return rows


def test_the_oracle_finds_each_tail_from_exact_inspections() -> None:
    """Near-exact inspections put each tail's posterior at its own growth draw: its p50 after
    year 5 is its true crack (to the grid's spacing) and its P(critical) by the horizon says
    whether it gets there.  A wrong flight index, law or likelihood fails."""
    rows = _bulkhead_oracle(0.002, 4)
    assert len(rows) > 6
    assert (rows["p50_m"] / rows["true_m"] - 1).abs().max() < 0.05  # grid: 0.025 apart in ln f
    assert (rows["prob_critical"] - rows["reaches"]).abs().median() < 0.05


def test_the_oracle_bands_hold_under_sizing_error() -> None:
    """Under the method's 4 % sizing error the oracle's [p05, p95] holds about 90 % of the
    cracks after year 5 (30 tails: at least 80 %)."""
    rows = _bulkhead_oracle(0.04, 10)
    held = (rows["p05_m"] <= rows["true_m"]) & (rows["true_m"] <= rows["p95_m"])
    assert held.mean() >= 0.8
