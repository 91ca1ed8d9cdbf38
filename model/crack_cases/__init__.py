"""Crack cases: beta(a) of the standard geometries from their published solutions, as a
structures engineer chooses them in AFGROW or NASGRO, tabulated for the march
(model.crack_cases.tabulate) and with the critical crack they give
(model.crack_cases.residual_strength).  One module per family; each case names its source."""

from __future__ import annotations

import dataclasses
from typing import Any

from model.crack_cases.base import CrackCase, ValidityLimit
from model.crack_cases.centre import CentreCrack
from model.crack_cases.corner import CornerCrackAtHole
from model.crack_cases.edge import SingleEdgeCrack
from model.crack_cases.hole import CrackAtHole
from model.crack_cases.surface import SurfaceCrack
from model.crack_cases.table import UserTable

CASES: dict[str, type[CrackCase]] = {
    case.type_name: case
    for case in (
        CentreCrack,
        SingleEdgeCrack,
        CrackAtHole,
        CornerCrackAtHole,
        SurfaceCrack,
        UserTable,
    )
}

__all__ = ["CASES", "CrackCase", "CrackCaseError", "ValidityLimit", "case_from_dict"]


class CrackCaseError(ValueError):
    """A crack case that cannot be built, with the dimension at fault (`field`, None where the
    fault is the type)."""

    def __init__(self, field: str | None, message: str) -> None:
        super().__init__(message)
        self.field = field


def case_from_dict(data: dict[str, Any]) -> CrackCase:
    """The case {"type": name, dimension: value, ...}; raises CrackCaseError naming the type or
    the dimension (unknown, missing or invalid)."""
    name = data.get("type")
    if name not in CASES:
        raise CrackCaseError("type", f"type must be one of {', '.join(CASES)}, got {name!r}")
    cls = CASES[name]
    known: dict[str, dataclasses.Field[Any]] = {
        f.name: f
        for f in dataclasses.fields(cls)  # type: ignore[arg-type]
    }
    values = {k: v for k, v in data.items() if k != "type"}
    for key in values:
        if key not in known:
            raise CrackCaseError(key, f"{name} takes {', '.join(known)}; not {key!r}")
    for key, field in known.items():
        no_default = field.default is dataclasses.MISSING
        if no_default and field.default_factory is dataclasses.MISSING and key not in values:
            raise CrackCaseError(key, f"{name} needs {key}")
        value = values.get(key)
        if key in values and value is None and "None" not in str(field.type):
            raise CrackCaseError(key, f"{name} needs {key}, not null")
        if str(field.type).startswith("tuple") and key in values:
            # a list of numbers, as JSON sends one ("12" read as a sequence was (1.0, 2.0))
            if not isinstance(value, list | tuple) or not all(map(_is_number, value)):
                raise CrackCaseError(key, f"{key} must be a list of numbers")
            values[key] = value = tuple(value)
        numeric = str(field.type).split(" |")[0] in ("float", "int")
        if numeric and value is not None and not _is_number(value):
            raise CrackCaseError(key, f"{key} must be a number, got {value!r}")
    try:
        return cls(**values)
    except (ValueError, TypeError) as exc:
        message = str(exc)
        named = next((key for key in known if message.startswith(key)), None)
        raise CrackCaseError(named, message) from exc


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)
