"""A long-lived `fleetpinn worker` process runs below the API (FLEETPINN_WORKER_NICE), so a
retrain on the API's cores takes the CPU that requests leave; its cache thread runs halfway
(tomorrow's risk and other locations' bands take less of the API's CPU)."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import pytest

from app import migrate
from tests.app.conftest import settings_in
from tests.app.servers import worker

# alone after the parallel run (Makefile pytest): reads process and thread priorities while they
# change
pytestmark = pytest.mark.serial

T = TypeVar("T")


def _poll(process: Any, read: Callable[[], T], done: Callable[[T], bool]) -> T:
    """read() every 50 ms until done(it) holds, the worker exits or 60 s pass; the last read."""
    deadline = time.monotonic() + 60
    seen = read()
    while time.monotonic() < deadline and process.process.poll() is None and not done(seen):
        time.sleep(0.05)
        seen = read()
    return seen


def test_a_worker_process_lowers_its_own_priority(tmp_path: Path) -> None:
    url = settings_in(tmp_path).database_url
    migrate.upgrade(url)
    mine = os.getpriority(os.PRIO_PROCESS, 0)
    process = worker(url, tmp_path, FLEETPINN_WORKER_NICE="7")
    try:
        seen = _poll(
            process,
            lambda: os.getpriority(os.PRIO_PROCESS, process.process.pid),
            lambda nice: nice != mine,
        )
        assert seen == min(19, mine + 7), process.text()
    finally:
        process.stop()


def _thread_nices(pid: int) -> set[int]:
    """The nice value of each thread of process `pid` (/proc: field 19 of each task's stat)."""
    found = set()
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            stat = (task / "stat").read_text()
        except FileNotFoundError:  # a thread that ended meanwhile
            continue
        found.add(int(stat.rsplit(")", 1)[1].split()[16]))
    return found


def test_the_worker_process_cache_thread_runs_halfway(tmp_path: Path) -> None:
    url = settings_in(tmp_path).database_url
    migrate.upgrade(url)
    mine = os.getpriority(os.PRIO_PROCESS, 0)
    process = worker(url, tmp_path, FLEETPINN_WORKER_NICE="8")
    wanted = {min(19, mine + 8), min(19, mine + 4)}
    try:
        seen = _poll(process, lambda: _thread_nices(process.process.pid), wanted.issubset)
        assert wanted <= seen, (seen, process.text())
    finally:
        process.stop()
