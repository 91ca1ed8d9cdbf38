"""Flights sent as cycles or as stress histories: counted by rainflow, reduced to one range under
the configured law, stored as sent; bad ones refused naming the flight and the field."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd
import pytest
import rainflow
from fastapi.testclient import TestClient
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.config import Settings
from app.db import make_engine
from app.services.records import spectra
from app.services.records.history import load_history
from app.services.records.stored_spectra import with_stored_cycles
from app.tables import Aircraft, Flight, FlightBlock, SpectrumBlock
from model.cycle_counting import CycleError, FlightCycles, from_cycles, from_history
from model.growth_laws import GROWTH_LAWS, GrowthConstants
from tests.app.conftest import flights

# ASTM E1049-85 (2017), Fig. 6: the rainflow counting example, and its counts (range: cycles)
E1049_HISTORY = [-2.0, 1.0, -3.0, 5.0, -1.0, 3.0, -4.0, 4.0, -2.0]
E1049_COUNTS = {3.0: 0.5, 4.0: 1.5, 6.0: 0.5, 8.0: 1.0, 9.0: 0.5}


def test_rainflow_counts_equal_the_librarys_on_the_astm_e1049_example() -> None:
    assert dict(rainflow.count_cycles(E1049_HISTORY)) == E1049_COUNTS
    # in MPa, shifted up so every cycle has a tensile maximum: the same ranges and counts
    shifted = [s + 10.0 for s in E1049_HISTORY]
    cycles = from_history(shifted)
    counted: dict[float, float] = {}
    for rng, count in zip(cycles.stress_range_mpa, cycles.count, strict=True):
        counted[float(rng)] = counted.get(float(rng), 0.0) + float(count)
    assert counted == E1049_COUNTS
    # R = S_min / S_max of each cycle, from the library's mean and range
    for (rng, mean, _, _, _), ratio in zip(
        rainflow.extract_cycles(shifted), cycles.load_ratio, strict=True
    ):
        assert ratio == pytest.approx((mean + 10.0 - rng / 2 - 10.0) / (mean + rng / 2))
    # a compressive-only cycle never opens the crack: dropped
    history = [-10.0, -2.0, -8.0, 5.0]
    library = list(rainflow.extract_cycles(history))
    kept = [c for c in library if c[1] + c[0] / 2 > 0]
    assert len(from_history(history)) == len(kept) < len(library)


def test_cycles_in_both_forms_and_bad_values_name_the_field() -> None:
    both = from_cycles(
        [
            {"stress_range_mpa": 90.0, "load_ratio": -0.1},
            {"max_stress_mpa": 80.0, "min_stress_mpa": 40.0, "count": 2.0},
        ]
    )
    assert both.stress_range_mpa.tolist() == [90.0, 40.0]
    assert both.load_ratio.tolist() == [-0.1, 0.5]
    assert both.count.tolist() == [1.0, 2.0]
    for bad, field in (
        ([{"stress_range_mpa": 90.0, "load_ratio": 1.0}], "cycles[0].load_ratio"),
        ([{"max_stress_mpa": 50.0, "min_stress_mpa": 60.0}], "cycles[0].min_stress_mpa"),
        ([{"stress_range_mpa": 90.0}], "cycles[0]"),
        ([{"stress_range_mpa": 9.0, "load_ratio": 0.1, "count": 0}], "cycles[0].count"),
    ):
        with pytest.raises(CycleError) as failed:
            from_cycles(bad)
        assert failed.value.field == field
    for history, reason in (
        ([1.0], "at least 2"),
        ([1.0, math.nan], "finite"),
        ([1, "x"], "number"),
    ):
        with pytest.raises(CycleError, match=reason):
            from_history(history)


def _spectra_rows(settings: Settings) -> int:
    engine = make_engine(settings.database_url)
    try:
        with Session(engine) as session:
            flights = session.scalar(select(func.count()).select_from(FlightBlock)) or 0
            blocks = session.scalar(select(func.count()).select_from(SpectrumBlock)) or 0
            # a block is written only with flights that refer to it
            assert (flights == 0) == (blocks == 0)
            return int(flights)
    finally:
        engine.dispose()


def _batch() -> list[dict[str, Any]]:
    batch = flights(3)
    batch[1].pop("stress_range_mpa")
    batch[1]["cycles"] = [
        {"stress_range_mpa": 95.0, "load_ratio": -0.1},
        {"max_stress_mpa": 70.0, "min_stress_mpa": 42.0, "count": 3},
    ]
    batch[2].pop("stress_range_mpa")
    batch[2]["stress_history_mpa"] = [-8.0, 62.0, 40.0, 88.0, 55.0, 70.0, -5.0]
    return batch


def test_the_three_ways_to_send_loads_are_stored_as_sent(
    client: TestClient, settings: Settings
) -> None:
    client.put("/aircraft/N001")
    batch = _batch()
    answer = client.post("/aircraft/N001/flights", json=batch)
    assert answer.status_code == 201, answer.text
    assert answer.json()["inserted"] == 3
    # the flight's one range: its cycles' damage-equivalent range under the configured law
    law = settings.law()
    expected = (95.0**law.m + 3 * 28.0**law.m) ** (1 / law.m)
    cycles_flight = client.get("/aircraft/N001/flights/F0002").json()
    assert cycles_flight["stress_range_mpa"] == pytest.approx(expected, rel=1e-12)
    assert client.get("/aircraft/N001/flights/F0001").json()["stress_range_mpa"] == 100.0
    engine = make_engine(settings.database_url)
    with Session(engine) as session:
        aircraft = session.scalar(select(Aircraft.id).where(Aircraft.tail == "N001"))
        assert aircraft is not None
        assert spectra.stored(session, aircraft, "F0001") is None
        sent = spectra.stored(session, aircraft, "F0002")
        assert sent is not None and sent.recorded == "cycles"
        assert sent.cycles.count.tolist() == [1.0, 3.0]
        counted = spectra.stored(session, aircraft, "F0003")
        assert counted is not None and counted.recorded == "stress_history"
        assert counted.stress_history_mpa is not None
        assert counted.stress_history_mpa.tolist() == batch[2]["stress_history_mpa"]
        library = rainflow.extract_cycles(batch[2]["stress_history_mpa"])
        assert counted.cycles.count.tolist() == [c[2] for c in library if c[1] + c[0] / 2 > 0]
    engine.dispose()
    # an exact re-send stores nothing more
    again = client.post("/aircraft/N001/flights", json=batch)
    assert again.status_code == 200 and again.json()["duplicates"] == 3
    assert _spectra_rows(settings) == 2
    # deleting the tail deletes its flights and what they recorded
    assert client.delete("/aircraft/N001").status_code == 200
    assert _spectra_rows(settings) == 0


def test_walker_settings_weigh_each_cycles_load_ratio() -> None:
    settings = Settings(growth_law="walker", walker_gamma=0.5)
    records, recorded = spectra.with_ranges("N001", _batch(), settings)
    law = settings.law()
    walker = GROWTH_LAWS["walker"]
    assert walker.uses_gamma
    assert recorded is not None
    assert recorded.recorded.tolist() == [None, "cycles", "stress_history"]
    assert recorded.flight_id[1] == "F0002"
    cycles = recorded.cycles.flight(1)
    effective = cycles.stress_range_mpa * (1 - cycles.load_ratio) ** (law.gamma - 1)
    expected = float(np.sum(cycles.count * effective**law.m) ** (1 / law.m))
    assert records[1]["stress_range_mpa"] == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize(
    ("change", "field", "reason"),
    [
        ({"stress_history_mpa": [42.0]}, "stress_history_mpa", "at least 2 points"),
        ({"stress_history_mpa": [-9.0, -3.0]}, "stress_history_mpa", "tensile"),
        (
            {"cycles": [{"stress_range_mpa": 5.0}], "stress_history_mpa": None},
            "cycles[0]",
            "load_ratio",
        ),
        ({"cycles": [], "stress_history_mpa": None}, "cycles", "at least 1 cycle"),
        ({"stress_range_mpa": 90.0}, "stress_history_mpa", "exactly one of"),
    ],
)
def test_a_bad_flight_is_422_naming_the_flight_and_field_and_nothing_is_stored(
    client: TestClient, settings: Settings, change: dict[str, Any], field: str, reason: str
) -> None:
    client.put("/aircraft/N001")
    batch = _batch()
    batch[2].update(change)
    answer = client.post("/aircraft/N001/flights", json=batch)
    assert answer.status_code == 422, answer.text
    body = answer.json()
    assert (body["row"], body["column"]) == (3, field)
    assert "flight 'F0003'" in body["reason"] and reason in body["reason"]
    assert client.get("/aircraft/N001").json()["flight_count"] == 0
    assert _spectra_rows(settings) == 0


@pytest.mark.parametrize("values", [[1.0, "x", 3.0], [1.0, None, 2.0], "1 2 3"])
def test_a_non_numeric_history_is_422_naming_the_flights_position_and_field(
    client: TestClient, values: Any
) -> None:
    client.put("/aircraft/N001")
    batch = _batch()
    batch[2]["stress_history_mpa"] = values
    answer = client.post("/aircraft/N001/flights", json=batch)
    assert answer.status_code == 422
    assert "stress_history_mpa" in answer.text and "2" in answer.text
    assert client.get("/aircraft/N001").json()["flight_count"] == 0


def test_a_nan_in_a_history_is_refused(client: TestClient) -> None:
    client.put("/aircraft/N001")
    body = (
        '[{"flight_id": "F1", "flown_at": "2025-01-01T00:00:00Z", '
        '"stress_history_mpa": [1.0, NaN, 40.0]}]'
    )
    answer = client.post(
        "/aircraft/N001/flights", content=body, headers={"Content-Type": "application/json"}
    )
    assert answer.status_code == 422
    assert "stress_history_mpa" in answer.text
    assert client.get("/aircraft/N001").json()["flight_count"] == 0


def test_a_flight_recorded_as_cycles_keeps_its_range_theirs(
    client: TestClient, settings: Settings
) -> None:
    client.put("/aircraft/N001")
    assert client.post("/aircraft/N001/flights", json=_batch()).status_code == 201
    before = client.get("/aircraft/N001/flights/F0002").json()
    refused = client.patch("/aircraft/N001/flights/F0002", json={"stress_range_mpa": 50.0})
    assert refused.status_code == 422
    assert refused.json()["column"] == "stress_range_mpa"
    assert "recorded as cycles" in refused.json()["reason"]
    assert client.get("/aircraft/N001/flights/F0002").json() == before
    # its other values, and a one-range flight's range, may change as before
    moved = client.patch("/aircraft/N001/flights/F0002", json={"mission": "M3"})
    assert moved.status_code == 200
    assert (
        client.patch("/aircraft/N001/flights/F0001", json={"stress_range_mpa": 90.0}).status_code
        == 200
    )
    assert _spectra_rows(settings) == 2


def _cycle_file(flights: list[tuple[str, str, list[tuple[float, float, float]]]]) -> bytes:
    rows = [
        {
            "tail": tail,
            "flight_id": flight_id,
            "flown_at": f"2025-01-0{flight_id[-1]}T00:00:00Z",
            "stress_range_mpa": rng,
            "load_ratio": ratio,
            "count": count,
        }
        for tail, flight_id, cycles in flights
        for rng, ratio, count in cycles
    ]
    return pd.DataFrame(rows).to_csv(index=False).encode()


def test_a_cycle_file_sent_again_with_new_flights_stores_each_new_flights_own_cycles(
    client: TestClient, settings: Settings
) -> None:
    """Re-sent flights are duplicates and keep their one stored row; the new ones, between
    them in the file, each get their own cycles (not a neighbour's)."""
    first = [
        ("A1", "F1", [(90.0, -0.1, 1.0), (20.0, 0.5, 2.0)]),
        ("B2", "F1", [(80.0, 0.0, 1.0)]),
        ("A1", "F3", [(70.0, 0.1, 1.0), (30.0, 0.6, 0.5), (10.0, 0.2, 3.0)]),
    ]
    later = [
        ("A1", "F2", [(60.0, 0.3, 4.0)]),
        ("B2", "F2", [(50.0, -0.2, 1.0), (25.0, 0.4, 1.0)]),
    ]

    def upload(body: bytes) -> dict[str, int]:
        files = {"file": ("cycles.csv", body, "text/csv")}
        answer = client.post("/flights/upload", files=files)
        assert answer.status_code in (200, 201), answer.text
        return answer.json()

    assert upload(_cycle_file(first))["inserted"] == 3
    mixed = [first[0], later[0], first[1], later[1], first[2]]
    assert upload(_cycle_file(mixed)) == {"inserted": 2, "duplicates": 3, "aircraft_created": 0}
    assert _spectra_rows(settings) == 5
    engine = make_engine(settings.database_url)
    with Session(engine) as session:
        for tail, flight_id, cycles in mixed:
            aircraft = session.scalar(select(Aircraft.id).where(Aircraft.tail == tail))
            assert aircraft is not None
            sent = spectra.stored(session, aircraft, flight_id)
            assert sent is not None and sent.recorded == "cycles"
            assert np.stack(sent.cycles.columns, axis=1).tolist() == [list(c) for c in cycles]
    engine.dispose()


def test_a_deleted_flights_cycles_count_nowhere_and_its_resend_stores_its_new_ones(
    client: TestClient, settings: Settings
) -> None:
    """One upload's flights of a tail share a block: deleting one of them leaves its cycles in
    the block, yet no reader counts them (stored, the tail page's summary, the cache's and the
    retrain's readers all start from the stored flights); the flight sent again with other
    cycles reads those, and a block goes with its last flight."""
    first = [
        ("A1", "F1", [(90.0, -0.1, 1.0), (20.0, 0.5, 2.0)]),
        ("A1", "F2", [(80.0, 0.0, 1.0)]),
        ("A1", "F3", [(70.0, 0.1, 1.0), (30.0, 0.6, 0.5)]),
    ]
    resent = ("A1", "F2", [(60.0, 0.3, 4.0), (15.0, 0.7, 1.0)])
    files = {"file": ("cycles.csv", _cycle_file(first), "text/csv")}
    assert client.post("/flights/upload", files=files).status_code == 201
    assert client.delete("/aircraft/A1/flights/F2").status_code == 200
    engine = make_engine(settings.database_url)

    def blocks() -> int:
        with Session(engine) as session:
            return int(session.scalar(select(func.count()).select_from(SpectrumBlock)) or 0)

    def read(expected: dict[str, list[tuple[float, float, float]]]) -> None:
        with Session(engine) as session:
            aircraft = session.scalar(select(Aircraft.id).where(Aircraft.tail == "A1"))
            assert aircraft is not None
            for flight_id in ("F1", "F2", "F3"):
                sent = spectra.stored(session, aircraft, flight_id)
                if flight_id not in expected:
                    assert sent is None
                    continue
                assert sent is not None
                assert np.stack(sent.cycles.columns, axis=1).tolist() == [
                    list(c) for c in expected[flight_id]
                ]
            summary = spectra.summary(session, aircraft)
            assert summary is not None and summary.flights == len(expected)
            counts = sum(c[2] for cycles in expected.values() for c in cycles)
            assert summary.cycles_per_flight == pytest.approx(counts / len(expected))
            # the cache's reader (app.services.forecasts.cache_advance) and the retrain's
            refs = session.execute(
                select(Flight.flight_id, FlightBlock.spectrum_block_id, FlightBlock.spectrum_index)
                .outerjoin(FlightBlock, FlightBlock.flight_pk == Flight.id)
                .where(Flight.aircraft_id == aircraft)
                .order_by(Flight.flight_id)
            ).all()
            blobs = spectra.blobs_of(session, [r[1] for r in refs], [r[2] for r in refs])
            assert {
                r[0]: FlightCycles.unpacked(b).packed() for r, b in zip(refs, blobs, strict=True)
            } == {
                f: FlightCycles(*np.array(c, dtype=np.float64).T).packed()
                for f, c in expected.items()
            }
            history = load_history(session, [aircraft], initial_crack_m=0.005)
            assert history is not None
            walker = GrowthConstants(1e-10, 3.5, 0.5)
            loaded = with_stored_cycles(session, history, "walker", walker).data.loads.cycles
            assert loaded is not None
            order = sorted(expected)  # flown_at follows the flight ids (_cycle_file)
            for k, flight_id in enumerate(order):
                cycles = expected[flight_id]
                assert loaded.count[0, k, : len(cycles)].tolist() == [c[2] for c in cycles]
                assert loaded.count[0, k, len(cycles) :].sum() == 0.0

    try:
        read({"F1": first[0][2], "F3": first[2][2]})
        assert blocks() == 1
        files = {"file": ("again.csv", _cycle_file([resent]), "text/csv")}
        assert client.post("/flights/upload", files=files).json()["inserted"] == 1
        read({"F1": first[0][2], "F2": resent[2], "F3": first[2][2]})
        assert blocks() == 2
        # the first block goes with the last of its flights, the second with its one flight
        assert client.delete("/aircraft/A1/flights/F1").status_code == 200
        assert client.delete("/aircraft/A1/flights/F3").status_code == 200
        assert blocks() == 1
        read({"F2": resent[2]})
        assert client.delete("/aircraft/A1/flights/F2").status_code == 200
        assert blocks() == 0
    finally:
        engine.dispose()
