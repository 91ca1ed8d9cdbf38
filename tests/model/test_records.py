from __future__ import annotations

import pickle

import pandas as pd
import pytest
import torch

from model.record_validation import (
    load_flights,
    load_inspections,
    validate_flights,
    validate_inspections,
)
from model.records import RecordError, read_table, write_table
from model.training_data import assemble

FLIGHTS = """
tail,flight_id,flown_at,stress_range_mpa,mission
N2,b2,2020-01-01T06:00:00Z,110,m2
N1,a1,2020-01-01T00:00:00Z,100,m1
N1,a2,2020-01-01T06:00:00+00:00,92.5,
N1,a3,2020-01-02 00:00:00,130,m3
N2,b1,2020-01-01T00:00:00Z,100,m1
"""

INSPECTIONS = """
tail,inspection_id,inspected_at,crack_length_m
N1,i1,2020-01-01T06:00:00Z,0.006
N1,i0,2019-12-31T00:00:00Z,0.005
N2,i2,2021-01-01T00:00:00Z,0.007
"""


def test_valid_flights_are_normalised(write_csv):
    flights = load_flights(write_csv("flights.csv", FLIGHTS))
    assert list(flights.columns) == ["tail", "flight_id", "flown_at", "stress_range_mpa", "mission"]
    assert str(flights["flown_at"].dtype) == "datetime64[ns, UTC]"
    assert flights["stress_range_mpa"].dtype == "float64"
    assert flights.loc[3, "mission"] is None and flights.loc[1, "mission"] == "m2"
    # naive time is UTC; the index is the 1-based data row
    assert flights.loc[4, "flown_at"] == pd.Timestamp("2020-01-02", tz="UTC")
    assert list(flights.index) == [1, 2, 3, 4, 5]


def test_csv_and_parquet_round_trip(write_csv, tmp_path):
    flights = load_flights(write_csv("flights.csv", FLIGHTS))
    flights.reset_index(drop=True).to_parquet(tmp_path / "flights.parquet")
    again = load_flights(tmp_path / "flights.parquet")
    pd.testing.assert_frame_equal(flights, again)


@pytest.mark.parametrize(
    ("line", "column", "reason"),
    [
        ("N1,a9,2020-01-03T00:00:00Z,-3,", "stress_range_mpa", "must be > 0, got -3"),
        ("N1,a9,2020-01-03T00:00:00Z,0,", "stress_range_mpa", "must be > 0, got 0"),
        ("N1,a9,2020-01-03T00:00:00Z,abc,", "stress_range_mpa", "must be a number, got 'abc'"),
        ("N1,a9,2020-01-03T00:00:00Z,inf,", "stress_range_mpa", "must be finite, got inf"),
        ("N1,a9,2020-01-03T00:00:00Z,,", "stress_range_mpa", "must not be blank"),
        (" ,a9,2020-01-03T00:00:00Z,100,", "tail", "must not be blank"),
        ("N1,,2020-01-03T00:00:00Z,100,", "flight_id", "must not be blank"),
        ("N1,a9,yesterday,100,", "flown_at", "must be an ISO 8601 time, got 'yesterday'"),
        ("N1,a9,2020-13-01,100,", "flown_at", "must be an ISO 8601 time, got '2020-13-01'"),
        (
            "N1,a1,2020-01-01T00:00:00Z,101,m1",
            "flight_id",
            "flight_id 'a1' of tail 'N1' repeats row 2 with different values",
        ),
    ],
)
def test_bad_flight_row_is_located(write_csv, line, column, reason):
    path = write_csv("flights.csv", FLIGHTS.strip() + "\n" + line)
    with pytest.raises(RecordError) as err:
        load_flights(path)
    assert (err.value.source, err.value.row, err.value.column) == ("flights.csv", 6, column)
    assert err.value.reason == reason
    assert str(err.value) == f"flights.csv row 6, column {column}: {reason}"


def test_first_bad_row_wins_over_column_order(write_csv):
    text = FLIGHTS.strip() + "\nN1,a9,2020-01-03T00:00:00Z,-1,\nN1,,2020-01-03T00:00:00Z,1,"
    with pytest.raises(RecordError) as err:
        load_flights(write_csv("flights.csv", text))
    assert (err.value.row, err.value.column) == (6, "stress_range_mpa")


def test_exact_duplicate_rows_collapse(write_csv):
    path = write_csv("flights.csv", FLIGHTS.strip() + "\nN1,a1,2020-01-01T00:00:00Z,100,m1")
    flights = load_flights(path)
    assert len(flights) == 5 and 6 not in flights.index


def test_same_id_on_other_tails_is_fine():
    df = pd.DataFrame(
        {
            "tail": ["A", "B"],
            "flight_id": ["1", "1"],
            "flown_at": ["2020-01-01", "2020-01-01"],
            "stress_range_mpa": [100.0, 100.0],
        }
    )
    assert len(validate_flights(df)) == 2


def test_missing_column_and_unknown_suffix(write_csv, tmp_path):
    with pytest.raises(RecordError) as err:
        load_flights(write_csv("flights.csv", "tail,flight_id,flown_at\nN1,a,2020-01-01"))
    assert (err.value.row, err.value.column) == (None, "stress_range_mpa")
    assert str(err.value).startswith("flights.csv, column stress_range_mpa: missing column")
    (tmp_path / "flights.xlsx").write_text("x")
    with pytest.raises(RecordError, match=r"flights.xlsx: unknown file type '.xlsx'"):
        read_table(tmp_path / "flights.xlsx")


def test_ragged_csv_line_names_its_row(write_csv):
    with pytest.raises(RecordError) as err:
        read_table(write_csv("flights.csv", FLIGHTS.strip() + "\nN1,a9,2020-01-03,1,m,extra"))
    assert err.value.row == 6


def test_inspection_errors(write_csv):
    bad = INSPECTIONS.strip() + "\nN3,i3,2021-01-01,0.01"
    with pytest.raises(RecordError) as err:
        load_inspections(write_csv("inspections.csv", bad), known_tails=["N1", "N2"])
    assert (err.value.row, err.value.column) == (4, "tail")
    assert "unknown tail 'N3'" in err.value.reason
    bad = INSPECTIONS.strip() + "\nN1,i3,2021-01-01,-0.01"
    with pytest.raises(RecordError, match=r"row 4, column crack_length_m: must be > 0"):
        load_inspections(write_csv("inspections.csv", bad))
    bad = INSPECTIONS.strip() + "\nN1,i1,2020-01-01T06:00:00Z,0.007"
    with pytest.raises(RecordError, match=r"row 4, column inspection_id: .* repeats row 1"):
        load_inspections(write_csv("inspections.csv", bad))


def test_assemble_orders_flights_and_counts_flights_before_inspection(write_csv):
    flights = load_flights(write_csv("flights.csv", FLIGHTS))
    inspections = load_inspections(write_csv("inspections.csv", INSPECTIONS))
    data = assemble(flights, inspections)
    assert data.tails == ["N1", "N2"]
    expected = torch.tensor([[100.0, 92.5, 130.0], [100.0, 110.0, 0.0]], dtype=torch.float64)
    torch.testing.assert_close(data.loads.stress_range_mpa, expected)
    assert data.loads.lengths.tolist() == [3, 2]
    # i1 at 06:00 sees only the 00:00 flight (strictly before); i0 precedes all flights
    assert data.observations.aircraft.tolist() == [0, 0, 1]
    assert data.observations.flights.tolist() == [1, 0, 2]
    assert data.observations.crack_length_m.tolist() == [0.006, 0.005, 0.007]
    assert data.flights["flight_id"].tolist() == ["a1", "a2", "a3", "b1", "b2"]
    assert data.flights["flight"].tolist() == [1, 2, 3, 1, 2]


def test_assemble_breaks_time_ties_by_flight_id():
    df = pd.DataFrame(
        {
            "tail": ["A", "A", "A"],
            "flight_id": ["z", "b", "a"],
            "flown_at": ["2020-01-02", "2020-01-01", "2020-01-01"],
            "stress_range_mpa": [3.0, 2.0, 1.0],
        }
    )
    data = assemble(validate_flights(df))
    assert data.loads.stress_range_mpa.tolist() == [[1.0, 2.0, 3.0]]
    assert len(data.observations.aircraft) == 0


def test_assemble_rejects_inspection_of_tail_without_flights(write_csv):
    flights = load_flights(write_csv("flights.csv", FLIGHTS))
    inspections = validate_inspections(
        pd.DataFrame(
            {
                "tail": ["N9"],
                "inspection_id": ["x"],
                "inspected_at": ["2020-01-01"],
                "crack_length_m": [0.01],
            }
        )
    )
    with pytest.raises(RecordError, match=r"inspections row 1, column tail: unknown tail 'N9'"):
        assemble(flights, inspections)


def test_write_table_round_trips_exactly(tmp_path):
    flights = validate_flights(
        pd.DataFrame(
            {
                "tail": ["A", "A", "B"],
                "flight_id": ["1", "2", "1"],
                "flown_at": ["2020-01-01T00:00:00Z", "2020-01-01T06:00:00.25Z", "2020-01-01"],
                "stress_range_mpa": [0.1 + 0.2, 1e-300, 130.0],
                "mission": ["M1", None, "a,b"],
            }
        )
    )
    for name in ("out.csv", "out.parquet"):
        write_table(flights.reset_index(drop=True), tmp_path / name)
        pd.testing.assert_frame_equal(load_flights(tmp_path / name), flights)
    assert "2020-01-01T06:00:00.250000Z" in (tmp_path / "out.csv").read_text()


def test_record_error_survives_pickling():
    error = pickle.loads(pickle.dumps(RecordError("f.csv", 3, "tail", "must not be blank")))
    assert (error.source, error.row, error.column) == ("f.csv", 3, "tail")
    assert str(error) == "f.csv row 3, column tail: must not be blank"


def test_an_error_quotes_a_prefix_of_a_long_cell(write_csv):
    """A 50 kB cell came back whole in the error (and in the upload's 422)."""
    cell = "x" * 50_000
    path = write_csv(
        "flights.csv",
        f"tail,flight_id,flown_at,stress_range_mpa\nH1,F1,2024-01-01T00:00:00Z,{cell}\n",
    )
    with pytest.raises(RecordError) as caught:
        load_flights(path)
    assert caught.value.reason == f"must be a number, got '{'x' * 199}… (50002 characters)"
