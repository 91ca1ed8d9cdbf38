"""(De)serialise a trained crack model: spec + weights + metrics, no pickled code.

The file is a torch archive holding only tensors and JSON strings, read back with
`weights_only=True`, so loading never executes code from the file.  An optional "posterior"
entry (a dict of tensors and JSON strings, model.uncertainty.LaplacePosterior.to_dict) rides
beside the weights; files without one (all older files) read as having none.
"""

from __future__ import annotations

import io
import json
from dataclasses import asdict
from pathlib import Path
from typing import Any

import torch

from model.cells import InputBox
from model.extrapolation import Extrapolation
from model.geometry import GeometryTable
from model.hybrid import CrackGrowthModel, ModelSpec
from model.nasgro import NasgroTerms
from model.physics import ParisLaw

FORMAT_VERSION = 1


def spec_to_dict(spec: ModelSpec) -> dict[str, Any]:
    return {
        "kernel": spec.kernel,
        "hidden": [list(layer) for layer in spec.hidden],
        "law": _law_to_dict(spec.law),
        "box": None if spec.box is None else asdict(spec.box),
        "growth_law": spec.growth_law,
        "step": spec.step,
        "extrapolation": None if spec.extrapolation is None else spec.extrapolation.to_dict(),
        "path_sd": spec.path_sd,
    }


def _law_to_dict(law: ParisLaw) -> dict[str, Any]:
    """The law's fields; a geometry table as its points and NASGRO terms as theirs, and no
    key without them or without a gamma below R = 0 (so files of a constant F and no NASGRO
    terms read as they did, and older fleetpinn reads them)."""
    data = asdict(law)
    table = data.pop("geometry_table")
    if table is not None:
        data["geometry_table"] = {k: list(v) for k, v in table.items()}
    if data["nasgro"] is None:
        del data["nasgro"]
    if data["gamma_below_zero"] is None:
        del data["gamma_below_zero"]
    return data


def _law_from_dict(data: dict[str, Any]) -> ParisLaw:
    fields = dict(data)
    table = fields.pop("geometry_table", None)  # files written before tables: a constant F
    nasgro = fields.pop("nasgro", None)
    return ParisLaw(
        **fields,
        geometry_table=None if table is None else GeometryTable.from_dict(table),
        nasgro=None if nasgro is None else NasgroTerms(**nasgro),
    )


def spec_from_dict(data: dict[str, Any]) -> ModelSpec:
    box = data.get("box")
    law = _law_from_dict(data["law"])
    extrapolation = data.get("extrapolation")  # files written before it: none
    return ModelSpec(
        kernel=data["kernel"],
        hidden=tuple((int(u), str(a)) for u, a in data["hidden"]),
        law=law,
        box=None
        if box is None
        else InputBox(tuple(box["stress_range_mpa"]), tuple(box["crack_length_m"])),
        growth_law=data.get("growth_law", "paris"),  # files written before growth laws had names
        step=data.get("step", "euler"),
        extrapolation=None
        if extrapolation is None
        else Extrapolation.from_dict(extrapolation, law),
        path_sd=float(data.get("path_sd", 0.0)),
    )


def to_bytes(
    model: CrackGrowthModel,
    metrics: dict[str, Any] | None = None,
    posterior: dict[str, Any] | None = None,
) -> bytes:
    """Serialise a model, its training/validation metrics (JSON-compatible values) and
    optionally its posterior (tensors and strings: LaplacePosterior.to_dict())."""
    archive: dict[str, Any] = {
        "format_version": FORMAT_VERSION,
        "spec": json.dumps(spec_to_dict(model.spec)),
        "metrics": json.dumps(metrics or {}),
        "state": {k: v.detach().cpu() for k, v in model.state_dict().items()},
    }
    if posterior is not None:
        archive["posterior"] = posterior
    buffer = io.BytesIO()
    torch.save(archive, buffer)
    return buffer.getvalue()


def posterior_from_bytes(data: bytes) -> dict[str, Any] | None:
    """The posterior entry of a model file (for LaplacePosterior.from_dict), None if it has none.
    Raises ValueError for a damaged file or one from a newer format version."""
    posterior = _read_archive(data).get("posterior")
    if posterior is not None and not isinstance(posterior, dict):
        raise ValueError("model file's posterior entry is not a dict")
    return posterior


def _read_archive(data: bytes) -> dict[str, Any]:
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
    return archive


def from_bytes(data: bytes) -> tuple[CrackGrowthModel, dict[str, Any]]:
    """Rebuild a model; raises ValueError for a damaged file or one from a newer format version."""
    archive = _read_archive(data)
    model = CrackGrowthModel(spec_from_dict(json.loads(archive["spec"])))
    model.load_state_dict(archive["state"])
    return model, json.loads(archive["metrics"])


def save(
    model: CrackGrowthModel,
    path: str | Path,
    metrics: dict[str, Any] | None = None,
    posterior: dict[str, Any] | None = None,
) -> None:
    Path(path).write_bytes(to_bytes(model, metrics, posterior))


def load(path: str | Path) -> tuple[CrackGrowthModel, dict[str, Any]]:
    return from_bytes(Path(path).read_bytes())
