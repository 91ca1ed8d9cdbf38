"""Shared test setup: one torch thread (the test machine is shared) and small record files."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

torch.set_num_threads(1)

# The files that hold a worker longest (1-4 min each, measured with `pytest --durations`) go
# first: `make test` hands files to its workers in collection order (pytest-xdist --dist
# loadfile), and one of them last kept one worker busy while the other sat idle.
LONGEST_FIRST = (
    "tests/app/test_crash.py",
    "tests/app/test_tour.py",
    "tests/model/test_identify.py",
    "tests/app/test_races.py",
    "tests/app/test_location_models.py",
    "tests/app/test_browser.py",
    "tests/app/test_real_data.py",
    "tests/app/test_e2e.py",
    "tests/app/test_fuzz.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    rank = {path: i for i, path in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))


@pytest.fixture
def write_csv(tmp_path: Path):
    """Write CSV text (header + lines) to tmp_path/name and return the path."""

    def write(name: str, text: str) -> Path:
        path = tmp_path / name
        path.write_text(text.strip() + "\n")
        return path

    return write
