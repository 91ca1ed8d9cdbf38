"""The tail page's load summary: flights recorded as cycles, cycles per flight, the R mix."""

from __future__ import annotations

import re
from datetime import timedelta

from fastapi.testclient import TestClient

from app.local_server import wait_for_job
from tests.app.conftest import START, add_tail, flights, inspect


def test_the_tail_page_shows_cycles_per_flight_and_the_load_ratio_mix(client: TestClient) -> None:
    add_tail(client, "ONE", 20)  # one range per flight: no spectra rows on its page
    assert client.put("/aircraft/SPEC").status_code == 201
    batch = flights(20)
    for flight in batch[10:]:
        flight.pop("stress_range_mpa")
        flight["cycles"] = [
            {"stress_range_mpa": 100.0, "load_ratio": -0.1},  # R < 0
            {"stress_range_mpa": 20.0, "load_ratio": 0.65, "count": 2},  # R >= 0.6
            {"max_stress_mpa": 60.0, "min_stress_mpa": 30.0, "count": 0.5},  # 0.3 <= R < 0.6
        ]
    assert client.post("/aircraft/SPEC/flights", json=batch).status_code == 201
    inspect(client, "SPEC", START + timedelta(days=4), 0.00502)
    inspect(client, "ONE", START + timedelta(days=4), 0.00502)
    wait_for_job(client, client.post("/models/retrain").json()["job_id"])
    html = client.get("/pages/aircraft/SPEC").text
    assert re.search(r"Flights recorded as cycles</th><td[^>]*>10<", html)
    assert re.search(r'id="cycles-per-flight">3.5<', html)  # 1 + 2 + 0.5
    mix = re.search(r'id="load-ratio-mix">(.*?)</td>', html)
    assert mix is not None
    shares = mix.group(1)
    assert "R &lt; 0: 29 %" in shares and "0 ≤ R &lt; 0.3: 0 %" in shares  # 1 of 3.5
    assert "0.3 ≤ R &lt; 0.6: 14 %" in shares and "R ≥ 0.6: 57 %" in shares
    assert "load-ratio-mix" not in client.get("/pages/aircraft/ONE").text
