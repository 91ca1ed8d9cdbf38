"""The cycle file read as flights and their cycles, in whatever order its rows come."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from model.cycle_counting import spectrum_of
from model.growth_laws import GROWTH_LAWS, GrowthConstants
from model.spectrum_files import CycleTable, cycle_table, cycles_to_flights

CONSTANTS = GrowthConstants(1e-10, 3.5, 0.6)


def _file() -> pd.DataFrame:
    rng = np.random.default_rng(4)
    rows = []
    for tail in ("A", "B"):
        for flight in range(1, 6):
            for _ in range(int(rng.integers(1, 5))):
                rows.append(
                    {
                        "tail": tail,
                        "flight_id": f"F{flight}",
                        "flown_at": f"2025-01-0{flight}T00:00:00Z",
                        "stress_range_mpa": float(rng.uniform(10, 150)),
                        "load_ratio": float(rng.uniform(-0.3, 0.7)),
                        "count": float(rng.choice([0.5, 1.0, 2.0])),
                    }
                )
    return pd.DataFrame(rows)


def test_shuffled_rows_give_each_flight_its_own_cycles_in_file_order() -> None:
    ordered = _file()
    shuffled = ordered.sample(frac=1.0, random_state=1).reset_index(drop=True)
    flights, table = cycle_table(shuffled, "s.csv", "walker", CONSTANTS)
    _, by_key = cycles_to_flights(ordered, "o.csv", "walker", CONSTANTS)
    assert len(flights) == len(by_key) == 10
    for f, (tail, flight_id) in enumerate(zip(flights["tail"], flights["flight_id"], strict=True)):
        mine = shuffled[(shuffled["tail"] == tail) & (shuffled["flight_id"] == flight_id)]
        got = table.flight(f)
        columns = ("stress_range_mpa", "load_ratio", "count")
        assert np.stack(got.columns, axis=1).tolist() == mine[list(columns)].to_numpy().tolist()
        expected = by_key[(tail, flight_id)].equivalent_range("walker", CONSTANTS)
        assert flights["stress_range_mpa"][f] == pytest.approx(expected, rel=1e-12)
        # the stored bytes are the flight's own cycles, packed as FlightCycles packs them
        assert table.block(np.array([f]))[0] == got.packed()
    # a block of flights in any order: each one's cycles at its own starts
    chosen = np.array([7, 2, 3, 9])
    data, starts = table.block(chosen)
    assert data == b"".join(table.flight(int(f)).packed() for f in chosen)
    assert np.diff(starts).tolist() == [len(table.flight(int(f))) for f in chosen]


def test_a_flight_whose_rows_come_apart_is_one_flight() -> None:
    """Rows of A/F1, then B/F1, then A/F1 again: two flights, A/F1 with all three of its
    cycles (a file read flight by flight would have made three)."""
    rows = [
        ("A", "F1", 90.0),
        ("B", "F1", 80.0),
        ("A", "F1", 30.0),
    ]
    frame = pd.DataFrame(
        {
            "tail": [r[0] for r in rows],
            "flight_id": [r[1] for r in rows],
            "flown_at": ["2025-01-01T00:00:00Z"] * 3,
            "stress_range_mpa": [r[2] for r in rows],
            "load_ratio": 0.1,
            "count": 1.0,
        }
    )
    flights, table = cycle_table(frame, "split.csv", "walker", CONSTANTS)
    assert flights[["tail", "flight_id"]].values.tolist() == [["A", "F1"], ["B", "F1"]]
    assert table.flight(0).stress_range_mpa.tolist() == [90.0, 30.0]
    assert table.flight(1).stress_range_mpa.tolist() == [80.0]


@pytest.mark.parametrize("law", ["walker", "paris"])
def test_flights_back_to_back_reduce_as_the_padded_channels_bit_for_bit(law: str) -> None:
    """The cycle file's reduction (flights back to back) and the march's (padded channels) sum
    the same cycles in the same order: equal to the last bit, so an upload's ranges are what a
    later reduction of the stored cycles gives."""
    rng = np.random.default_rng(7)
    sizes = rng.integers(1, 11, size=200)
    starts = np.concatenate(([0], np.cumsum(sizes)))
    table = np.stack(
        [
            rng.uniform(5.0, 150.0, starts[-1]),
            rng.uniform(-0.3, 0.7, starts[-1]),
            rng.choice([0.5, 1.0, 3.0], starts[-1]),
        ],
        axis=1,
    )
    flights = CycleTable(table, starts)
    padded = spectrum_of([flights.flight(f) for f in range(len(sizes))])
    expected = GROWTH_LAWS[law].equivalent_range(padded, CONSTANTS)[0].numpy()
    got = GROWTH_LAWS[law].flights_equivalent_range(table, starts, CONSTANTS)
    assert got.tolist() == expected.tolist()
