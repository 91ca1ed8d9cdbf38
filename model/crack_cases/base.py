"""What every crack case is: beta(a) in K = beta S sqrt(pi a), its validity range, and the
section it leaves for net-section yield.

a is the crack the march tracks (model.geometry): the half-length of a centre crack, the depth
of an edge, surface or corner crack, the length from the hole's edge of a crack at a hole.  A
case is a small frozen dataclass whose dimensions are checked when it is made (ValueError
naming the dimension), so a case that exists can be evaluated anywhere in [0, extent).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, fields
from typing import ClassVar

import numpy as np

# where a body is infinite (Bowie's plate, a user table without a width): no crack in a part
# grows this far (m), so searches for a_crit end here
UNBOUNDED_M = 10.0
# the section's dimensions as the validity reasons name them (a/W, a/t, (2r + a)/W)
_SYMBOLS = {"hole_diameter_m": "2r", "thickness_m": "t", "width_m": "W"}


@dataclass(frozen=True)
class ValidityLimit:
    """The largest crack (m) inside the case's published validity range, and why it ends there
    (an a/W limit, a/t, the corner crack reaching the far face)."""

    crack_length_m: float
    reason: str


class CrackCase(ABC):
    """A crack case.  Subclasses are frozen dataclasses; `type_name` is how the catalogue names
    them (`crack_case: {"type": ...}`)."""

    type_name: ClassVar[str]

    def __post_init__(self) -> None:
        for field in fields(self):  # type: ignore[arg-type]
            value = getattr(self, field.name)
            is_length = field.name.endswith("_m") and value is not None
            if is_length and not (
                isinstance(value, int | float) and math.isfinite(value) and value > 0
            ):
                raise ValueError(f"{field.name} must be a finite length > 0 m, got {value!r}")
        self._check()

    def _check(self) -> None:  # noqa: B027 (a case without cross-checks needs none)
        """Raise ValueError naming the dimension where the dimensions contradict each other."""

    @abstractmethod
    def beta(self, crack_length_m: np.ndarray) -> np.ndarray:
        """beta at each crack (m, any shape): K / (S sqrt(pi a)) by the case's closed form."""

    @abstractmethod
    def validity(self) -> ValidityLimit:
        """Where the case's published validity range ends."""

    @abstractmethod
    def extent_m(self) -> float:
        """The crack at which the section is severed (or a bound far past any a_crit for an
        infinite body): the closed form is evaluated in [0, extent) only."""

    @abstractmethod
    def extent_reason(self) -> str:
        """What extent_m is, in the case's dimensions ('a = t: the crack reaches the back face'),
        so that a critical crack set by it says which dimension ended the crack."""

    def validity_said(self) -> str:
        """Where the validity range ends, for the texts a reader sees (the API's warnings), in
        mm as structures engineers read lengths: 'a = 40.00 mm (a/W = 0.8 (tada); W = 50.00
        mm)'.  The section's dimensions are named so that the limit can be checked by hand."""
        validity = self.validity()
        dimensions = [
            f"{symbol} = {mm(getattr(self, name))}"
            for name, symbol in _SYMBOLS.items()
            if getattr(self, name, None) is not None
        ]
        said = f"{validity.reason}; {', '.join(dimensions)}" if dimensions else validity.reason
        return f"a = {mm(validity.crack_length_m)} ({said})"

    def net_section_factor(self, crack_length_m: np.ndarray) -> np.ndarray | None:
        """Gross over net section area at each crack (the net-section stress is S times it), or
        None where the body is infinite and has no net section to yield."""
        return None

    def to_dict(self) -> dict[str, object]:
        """The catalogue's form: {"type": ..., dimensions}."""
        out: dict[str, object] = {"type": self.type_name}
        for field in fields(self):  # type: ignore[arg-type]
            value = getattr(self, field.name)
            out[field.name] = list(value) if isinstance(value, tuple) else value
        return out


def mm(length_m: float) -> str:
    """A length in a reader's text, in mm with 2 decimals as the service's pages show cracks:
    0.04 -> '40.00 mm' (fields and arguments stay in m)."""
    return f"{length_m * 1000:.2f} mm"


def secant_factor(x: np.ndarray) -> np.ndarray:
    """sqrt(sec(x)) for x in [0, pi/2): Feddersen's finite-width form."""
    return 1.0 / np.sqrt(np.cos(x))
