"""The compiled march's inlined elementary functions against Python's math (libm)."""

from __future__ import annotations

import math

import pytest
import torch

from model import fast_march_math as fmm


def test_compiled_math_matches_libm() -> None:
    """The inlined tanh, expm1, log and power (SIMD-friendly) against Python's math."""
    gen = torch.Generator().manual_seed(0)
    wide = torch.cat(
        (torch.randn(400, generator=gen, dtype=torch.float64) * 4, torch.logspace(-300, 2, 100))
    ).tolist()
    for x in [*wide, 0.0, 25.0, -25.0, 1e-12, -1e-12]:
        assert fmm.tanh(x) == pytest.approx(math.tanh(x), rel=1e-15, abs=0)
        assert fmm.expm1(min(x, 700.0)) == pytest.approx(math.expm1(min(x, 700.0)), rel=1e-15)
    for x in torch.logspace(-300, 300, 500, dtype=torch.float64).tolist():
        assert fmm.log(x) == pytest.approx(math.log(x), rel=1e-15, abs=1e-16)
    for x in torch.logspace(-3, 4, 200, dtype=torch.float64).tolist():
        assert fmm.power(x, 3.8) == pytest.approx(x**3.8, rel=1e-14)
        assert fmm.power(x, 2.8) == pytest.approx(x**2.8, rel=1e-14)
    assert fmm.power(1e100, 3.8) == math.inf
    assert fmm.paris_growth(math.nan, 1.0, 3.8) != fmm.paris_growth(math.nan, 1.0, 3.8)
    assert fmm.paris_growth(-math.inf, 1.0, 3.8) == 0.0
    assert fmm.paris_growth(math.inf, 1.0, 3.8) == math.inf
    assert fmm.paris_growth(-2.0, 1.0, 3.8) == 0.0
