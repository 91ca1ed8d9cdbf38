"""(De)serialise a trained crack model: spec + weights + metrics, no pickled code.

The file is a torch archive holding only tensors and JSON strings, read back with
`weights_only=True`, so loading never executes code from the file.
"""

from __future__ import annotations

import io
import json
from dataclasses import asdict
from pathlib import Path
from typing import Any

import torch

from model.cells import InputBox
from model.hybrid import CrackGrowthModel, ModelSpec
from model.physics import ParisLaw

FORMAT_VERSION = 1


def spec_to_dict(spec: ModelSpec) -> dict[str, Any]:
    return {
        "kernel": spec.kernel,
        "hidden": [list(layer) for layer in spec.hidden],
        "law": asdict(spec.law),
        "box": None if spec.box is None else asdict(spec.box),
    }


def spec_from_dict(data: dict[str, Any]) -> ModelSpec:
    box = data.get("box")
    return ModelSpec(
        kernel=data["kernel"],
        hidden=tuple((int(u), str(a)) for u, a in data["hidden"]),
        law=ParisLaw(**data["law"]),
        box=None
        if box is None
        else InputBox(tuple(box["stress_range_mpa"]), tuple(box["crack_length_m"])),
    )


def to_bytes(model: CrackGrowthModel, metrics: dict[str, Any] | None = None) -> bytes:
    """Serialise a model and its training/validation metrics (JSON-compatible values)."""
    buffer = io.BytesIO()
    torch.save(
        {
            "format_version": FORMAT_VERSION,
            "spec": json.dumps(spec_to_dict(model.spec)),
            "metrics": json.dumps(metrics or {}),
            "state": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        },
        buffer,
    )
    return buffer.getvalue()


def from_bytes(data: bytes) -> tuple[CrackGrowthModel, dict[str, Any]]:
    """Rebuild a model; raises ValueError for a damaged file or one from a newer format version."""
    try:
        archive = torch.load(io.BytesIO(data), weights_only=True, map_location="cpu")
    except Exception as exc:
        raise ValueError(f"not a fleetpinn model file: {exc}") from exc
    if not isinstance(archive, dict) or "format_version" not in archive:
        raise ValueError("not a fleetpinn model file: no format_version")
    version = int(archive["format_version"])
    if version > FORMAT_VERSION:
        raise ValueError(
            f"model file has format version {version}, newer than this fleetpinn reads "
            f"({FORMAT_VERSION}); upgrade fleetpinn to load it"
        )
    model = CrackGrowthModel(spec_from_dict(json.loads(archive["spec"])))
    model.load_state_dict(archive["state"])
    return model, json.loads(archive["metrics"])


def save(model: CrackGrowthModel, path: str | Path, metrics: dict[str, Any] | None = None) -> None:
    Path(path).write_bytes(to_bytes(model, metrics))


def load(path: str | Path) -> tuple[CrackGrowthModel, dict[str, Any]]:
    return from_bytes(Path(path).read_bytes())
