"""benchmarks/sbc.py's FleetPrior: its noise draws are the model's own priors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmarks.sbc import draw_fleet
from model.fleet_spread import SPREAD_PRIOR_SD
from model.tracking import SIZING_PRIOR_SD, SizingError


def test_both_noises_draw_the_same_geometry_and_protocol() -> None:
    for seed in range(40):
        model, uniform = draw_fleet(seed, noise="model"), draw_fleet(seed, noise="uniform")
        assert (model.geometry, model.discrepancy, model.protocol, model.inspected_share) == (
            uniform.geometry,
            uniform.discrepancy,
            uniform.protocol,
            uniform.inspected_share,
        )


def test_the_model_noise_is_the_spread_and_sizing_priors() -> None:
    """tau ~ |N(0, SPREAD_PRIOR_SD)|: root mean square SPREAD_PRIOR_SD; ln(sizing / 5 %) ~
    N(0, SIZING_PRIOR_SD), so 16 % of the draws lie above 10 %, which the uniform draw never
    gives."""
    draws = [draw_fleet(seed, noise="model") for seed in range(2000)]
    tau = np.array([d.growth_sd for d in draws])
    log_sizing = np.log([d.sizing_sd / SizingError().relative_sd for d in draws])
    assert math.sqrt(np.mean(tau**2)) == pytest.approx(SPREAD_PRIOR_SD, rel=0.05)
    assert np.std(log_sizing) == pytest.approx(SIZING_PRIOR_SD, rel=0.05)
    assert abs(np.mean(log_sizing)) < 0.05
    assert 0.13 < np.mean(log_sizing > math.log(2.0)) < 0.19
    assert max(d.sizing_sd for d in (draw_fleet(s, noise="uniform") for s in range(200))) <= 0.10
