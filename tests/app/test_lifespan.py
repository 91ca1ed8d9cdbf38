"""What each API process sets up in its lifespan, whichever way it was started (`fleetpinn serve`,
`uvicorn --workers N` spawning fresh processes, the tests' TestClient)."""

from __future__ import annotations

import gc
import threading

import torch
from anyio import to_thread

from app.config import Settings
from tests.app.conftest import serving


def _threads_of_a_new_thread() -> int:
    """torch's thread count as a thread started now sees it (the count is set per thread from
    the process-wide one on its first use, so a request's thread sees what the lifespan set)."""
    seen: list[int] = []
    thread = threading.Thread(target=lambda: seen.append(torch.get_num_threads()))
    thread.start()
    thread.join()
    return seen[0]


def test_an_api_process_sets_its_threads_and_freezes_its_start_up_heap(settings: Settings) -> None:
    """The worker thread used to be the only one to set it, so API processes beside `fleetpinn
    worker` processes ran torch's default pool (model.runtime says why that stalls)."""
    torch.set_num_threads(2)
    assert _threads_of_a_new_thread() == 2
    with serving(settings.model_copy(update={"run_worker": False, "request_threads": 3})) as api:
        assert api.get("/health").status_code == 200
        assert _threads_of_a_new_thread() == 1
        assert gc.get_freeze_count() > 100_000  # the start-up heap, out of the collector's sight

        async def tokens() -> float:
            return to_thread.current_default_thread_limiter().total_tokens

        assert api.portal is not None
        assert api.portal.call(tokens) == 3
