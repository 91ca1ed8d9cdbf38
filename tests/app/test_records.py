"""Stored records read back in bulk: whole tails, or only the rows of given keys."""

from collections.abc import Iterator
from datetime import timedelta

import pandas as pd
import pytest
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from app.config import Settings
from app.db import make_engine, make_session_factory
from app.services.records.stored_records import (
    FLIGHTS,
    INSPECTIONS,
    stored_by_key,
    stored_flights,
    stored_inspections,
    with_records,
)
from app.storage import chunks
from app.tables import Aircraft
from tests.app.conftest import START, add_tail, inspect


@pytest.fixture
def session(client: TestClient, settings: Settings) -> Iterator[Session]:
    add_tail(client, "A", 30, stress=[100.0, 120.0])
    add_tail(client, "B", 10)
    client.put("/aircraft/EMPTY")
    inspect(client, "A", START + timedelta(days=2), 0.0051)
    with make_session_factory(make_engine(settings.database_url))() as session:
        yield session


def _ids(session: Session) -> dict[str, int]:
    return {a.tail: a.id for a in session.query(Aircraft)}


def test_stored_by_key_reads_only_the_incoming_keys(session: Session) -> None:
    ids = _ids(session)
    keys = pd.DataFrame(
        {
            "aircraft_id": [ids["A"], ids["A"], ids["B"], ids["B"]],
            "flight_id": ["F0002", "F9999", "F0010", "F0002"],
        }
    )
    found = stored_by_key(session, FLIGHTS, keys)
    got = sorted(zip(found["aircraft_id"], found["flight_id"], strict=True))
    assert got == sorted([(ids["A"], "F0002"), (ids["B"], "F0010"), (ids["B"], "F0002")])
    row = found[(found["aircraft_id"] == ids["A"]) & (found["flight_id"] == "F0002")].iloc[0]
    assert row["stress_range_mpa"] == 120.0
    assert row["flown_at"] == pd.Timestamp(START + timedelta(hours=6))
    assert row["mission"] == "M1"
    empty = stored_by_key(
        session, INSPECTIONS, keys.iloc[:0].rename(columns={"flight_id": "inspection_id"})
    )
    assert empty.empty and list(empty.columns)[:2] == ["aircraft_id", "inspection_id"]


def test_whole_tails_and_which_tails_have_rows(session: Session) -> None:
    ids = _ids(session)
    flights = stored_flights(session, [ids["A"], ids["B"]])
    assert flights.groupby("tail").size().to_dict() == {"A": 30, "B": 10}
    assert str(flights["flown_at"].dt.tz) == "UTC"
    inspections = stored_inspections(session, list(ids.values()))
    assert inspections[["tail", "inspection_id", "detected", "repaired"]].values.tolist() == [
        ["A", "I-202401030000", True, False]
    ]
    assert sorted(with_records(session, FLIGHTS, list(ids.values()))) == sorted(
        [ids["A"], ids["B"]]
    )
    assert with_records(session, INSPECTIONS, list(ids.values())) == [ids["A"]]


def test_chunks_bound_every_in_list() -> None:
    assert [list(c) for c in chunks(list(range(7)), size=3)] == [[0, 1, 2], [3, 4, 5], [6]]
    assert list(chunks([], size=3)) == []
