import io
from datetime import timedelta

import pandas as pd
from fastapi.testclient import TestClient

from tests.app.conftest import START, flights


def _count(client: TestClient, tail: str) -> int:
    count: int = client.get(f"/aircraft/{tail}").json()["flight_count"]
    return count


def test_json_batch_is_stored_once(client: TestClient) -> None:
    client.put("/aircraft/N001")
    batch = flights(8)
    first = client.post("/aircraft/N001/flights", json=batch)
    assert first.status_code == 201
    assert first.json() == {"inserted": 8, "duplicates": 0, "aircraft_created": 0}
    again = client.post("/aircraft/N001/flights", json=batch + flights(10)[8:])
    assert again.status_code == 201
    assert again.json() == {"inserted": 2, "duplicates": 8, "aircraft_created": 0}
    resend = client.post("/aircraft/N001/flights", json=batch)
    assert resend.status_code == 200
    assert resend.json()["duplicates"] == 8
    assert _count(client, "N001") == 10


def test_same_flight_id_with_other_values_is_409_and_stores_nothing(client: TestClient) -> None:
    client.put("/aircraft/N001")
    client.post("/aircraft/N001/flights", json=flights(3))
    changed = flights(5)
    changed[1]["stress_range_mpa"] = 120.0
    answer = client.post("/aircraft/N001/flights", json=changed)
    assert answer.status_code == 409
    assert "F0002" in answer.json()["detail"]
    assert "stress_range_mpa" in answer.json()["detail"]
    assert _count(client, "N001") == 3


def test_invalid_row_is_422_naming_row_column_and_nothing_is_stored(client: TestClient) -> None:
    client.put("/aircraft/N001")
    batch = flights(5)
    batch[3]["stress_range_mpa"] = -4.0
    answer = client.post("/aircraft/N001/flights", json=batch)
    assert answer.status_code == 422
    body = answer.json()
    assert (body["row"], body["column"]) == (4, "stress_range_mpa")
    assert "> 0" in body["reason"]
    assert _count(client, "N001") == 0


def test_unparseable_json_value_is_422_naming_row_and_column(client: TestClient) -> None:
    client.put("/aircraft/N001")
    batch = flights(3)
    batch[2]["flown_at"] = "yesterday"
    body = client.post("/aircraft/N001/flights", json=batch).json()
    assert (body["row"], body["column"]) == (3, "flown_at")


def test_json_batch_for_unknown_tail_is_404(client: TestClient) -> None:
    assert client.post("/aircraft/GHOST/flights", json=flights(2)).status_code == 404


def _frame(tails: list[str], n: int) -> pd.DataFrame:
    rows = []
    for tail in tails:
        for f in flights(n):
            rows.append({"tail": tail, **f})
    return pd.DataFrame(rows)


def test_csv_upload_creates_unknown_tails(client: TestClient) -> None:
    client.put("/aircraft/A1")
    text = _frame(["A1", "B2", "C3"], 4).to_csv(index=False)
    answer = client.post("/flights/upload", files={"file": ("fleet.csv", text, "text/csv")})
    assert answer.status_code == 201
    assert answer.json() == {"inserted": 12, "duplicates": 0, "aircraft_created": 2}
    again = client.post("/flights/upload", files={"file": ("fleet.csv", text, "text/csv")})
    assert again.json() == {"inserted": 0, "duplicates": 12, "aircraft_created": 0}
    assert [_count(client, t) for t in ("A1", "B2", "C3")] == [4, 4, 4]


def test_parquet_upload_is_read_like_csv(client: TestClient) -> None:
    frame = _frame(["P1", "P2"], 3)
    frame["flown_at"] = pd.to_datetime(frame["flown_at"], utc=True)
    buffer = io.BytesIO()
    frame.to_parquet(buffer, index=False)
    # No suffix: the content (Parquet magic bytes) tells the type.
    answer = client.post("/flights/upload", files={"file": ("upload", buffer.getvalue())})
    assert answer.status_code == 201, answer.text
    assert answer.json() == {"inserted": 6, "duplicates": 0, "aircraft_created": 2}
    assert client.get("/aircraft/P2").json()["last_flown_at"] == "2024-01-01T12:00:00Z"


def test_bad_upload_row_stores_nothing_not_even_new_tails(client: TestClient) -> None:
    frame = _frame(["A1", "B2"], 3)
    frame.loc[4, "flown_at"] = "not a time"
    text = frame.to_csv(index=False)
    answer = client.post("/flights/upload", files={"file": ("fleet.csv", text)})
    assert answer.status_code == 422
    body = answer.json()
    assert (body["source"], body["row"], body["column"]) == ("fleet.csv", 5, "flown_at")
    assert client.get("/aircraft").json()["total"] == 0


def test_upload_missing_column_is_422(client: TestClient) -> None:
    text = "tail,flight_id,flown_at\nA,1,2024-01-01\n"
    body = client.post("/flights/upload", files={"file": ("f.csv", text)}).json()
    assert body["column"] == "stress_range_mpa"
    assert body["row"] is None


def test_upload_conflict_with_stored_flight_is_409(client: TestClient) -> None:
    first = _frame(["A1"], 2)
    client.post("/flights/upload", files={"file": ("a.csv", first.to_csv(index=False))})
    second = _frame(["A1", "B2"], 3)
    second.loc[1, "flown_at"] = (START + timedelta(hours=1)).isoformat()
    answer = client.post("/flights/upload", files={"file": ("b.csv", second.to_csv(index=False))})
    assert answer.status_code == 409
    assert "F0002" in answer.json()["detail"] and "flown_at" in answer.json()["detail"]
    assert client.get("/aircraft").json()["total"] == 1


def test_resend_with_nanoseconds_is_a_duplicate(client: TestClient) -> None:
    text = "tail,flight_id,flown_at,stress_range_mpa\nA1,1,2024-01-01T00:00:00.123456789Z,100\n"
    first = client.post("/flights/upload", files={"file": ("f.csv", text)})
    assert first.json()["inserted"] == 1
    again = client.post("/flights/upload", files={"file": ("f.csv", text)})
    assert again.json() == {"inserted": 0, "duplicates": 1, "aircraft_created": 0}
    assert client.get("/aircraft/A1").json()["last_flown_at"] == "2024-01-01T00:00:00.123456Z"


def test_upload_names_errors_after_the_client_file_and_ignores_its_path(
    client: TestClient,
) -> None:
    text = "tail,flight_id,flown_at,stress_range_mpa\nA1,1,2024-01-01,1,extra\n"
    body = client.post("/flights/upload", files={"file": ("../../x.csv", text)}).json()
    assert (body["source"], body["row"]) == ("x.csv", 1)
    odd = client.post("/flights/upload", files={"file": ("..", "tail\n")})
    assert odd.status_code == 422
    assert odd.json()["column"] == "flight_id"
