"""A thread's own CPU priority: the background threads (a worker's jobs and cache, an API
process's answers made ahead) run below the threads that answer requests."""

from __future__ import annotations

import os
import threading


def lower_this_thread(nice: int) -> None:
    """Lower the calling thread's CPU priority by `nice` (Linux threads each have their own)."""
    if nice:
        thread = threading.get_native_id()
        os.setpriority(os.PRIO_PROCESS, thread, os.getpriority(os.PRIO_PROCESS, thread) + nice)
