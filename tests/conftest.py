"""Shared test setup: one torch thread (the test machine is shared) and small record files."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

torch.set_num_threads(1)


@pytest.fixture
def write_csv(tmp_path: Path):
    """Write CSV text (header + lines) to tmp_path/name and return the path."""

    def write(name: str, text: str) -> Path:
        path = tmp_path / name
        path.write_text(text.strip() + "\n")
        return path

    return write
