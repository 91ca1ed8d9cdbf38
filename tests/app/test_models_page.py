"""The Models & jobs page says a refused retrain is refused, with the gate's reason and the
inspections its verdict blames (`culprits`, where the verdict lists them)."""

from __future__ import annotations

import re

from app.config import Settings
from app.services import audit
from app.services.jobs import queue as jobs
from tests.app.conftest import serving


def test_a_refused_retrain_reads_refused_with_its_culprits(settings: Settings) -> None:
    gate = {
        "passed": False,
        "reason": "candidate 43.3 % vs active 0.0092 %",
        "active_version": 1,
        "culprits": [{"tail": "T3", "inspection_id": "I-7", "error_pct": 152.25}, "T4 I-9"],
    }
    # no worker: one would claim the queued job (and fail it, with nothing to train on) before
    # the test records its result
    with (
        serving(settings.model_copy(update={"run_worker": False})) as client,
        client.app.state.session_factory() as session,  # type: ignore[attr-defined]
    ):
        job = jobs.enqueue(session, "retrain", {}, actor=audit.local("test"))
        job.status, job.progress, job.stage = "succeeded", 1.0, "done"
        job.result = {
            "model_version": 2,
            "activated": False,
            "outcome": "refused",
            "reason": "refused by the promotion gate: " + gate["reason"],
            "metrics": {"gate": gate},
        }
        session.commit()
        page = client.get("/pages/models").text
        listed = client.get("/jobs").json()[0]
    cell = re.search(r'<td class="outcome">(.*?)</td>', page, re.S)
    assert cell, "no outcome cell"
    text = " ".join(re.sub("<[^>]+>", " ", cell.group(1)).split())
    assert text == (
        "refused model v2 kept as a candidate candidate 43.3 % vs active 0.0092 % "
        "T3 I-7: error_pct 152.2 T4 I-9"
    )
    assert (listed["status"], listed["outcome"]) == ("succeeded", "refused")
