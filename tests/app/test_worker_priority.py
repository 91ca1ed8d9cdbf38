"""A long-lived `fleetpinn worker` process runs below the API (FLEETPINN_WORKER_NICE), so a
retrain on the API's cores takes the CPU that requests leave."""

from __future__ import annotations

import os
import time
from pathlib import Path

from app import migrate
from tests.app.conftest import settings_in
from tests.app.servers import worker


def test_a_worker_process_lowers_its_own_priority(tmp_path: Path) -> None:
    url = settings_in(tmp_path).database_url
    migrate.upgrade(url)
    mine = os.getpriority(os.PRIO_PROCESS, 0)
    process = worker(url, tmp_path, FLEETPINN_WORKER_NICE="7")
    try:
        deadline = time.monotonic() + 60
        seen = mine
        while time.monotonic() < deadline and process.process.poll() is None:
            seen = os.getpriority(os.PRIO_PROCESS, process.process.pid)
            if seen != mine:
                break
            time.sleep(0.05)
        assert seen == min(19, mine + 7), process.text()
    finally:
        process.stop()
