"""Rainflow counting of a stress history (model.cycle_counting.from_history): the cycles that
open the crack, with the range and load ratio of their own points."""

from __future__ import annotations

import numpy as np
import pytest

from model.cycle_counting import CycleError, from_history


def test_two_points_are_one_half_cycle() -> None:
    # ASTM E1049's residue; the rainflow package counts [120, 0] as no cycle at all
    cycles = from_history([120.0, 0.0])
    assert cycles.stress_range_mpa.tolist() == [120.0]
    assert cycles.load_ratio.tolist() == [0.0]
    assert cycles.count.tolist() == [0.5]
    assert from_history([-20.0, 100.0]).load_ratio.tolist() == [-0.2]


def test_a_tiny_tensile_peak_is_counted_from_its_own_points() -> None:
    # mean + range / 2 underflowed to 0 for 5e-324, and the flight was refused
    cycles = from_history([5e-324, 0.0, 0.0])
    assert cycles.stress_range_mpa.tolist() == [5e-324]
    assert cycles.count.tolist() == [0.5]


def test_a_history_reads_peaks_and_valleys_by_astm() -> None:
    # ASTM E1049-85's example (Fig. 6): ranges 3 and 4 half cycles, 4 a full one, ...
    history = [-2.0, 1.0, -3.0, 5.0, -1.0, 3.0, -4.0, 4.0, -2.0]
    cycles = from_history(np.array(history) + 10.0)
    ranges: dict[float, float] = {}
    for rng, count in zip(cycles.stress_range_mpa, cycles.count, strict=True):
        ranges[float(rng)] = ranges.get(float(rng), 0.0) + float(count)
    assert ranges == {3.0: 0.5, 4.0: 1.5, 6.0: 0.5, 8.0: 1.0, 9.0: 0.5}


@pytest.mark.parametrize("history", [[5.0, 5.0], [0.0, 0.0, 0.0], [-50.0, -10.0, -30.0]])
def test_no_cycle_that_opens_the_crack_is_refused(history: list[float]) -> None:
    with pytest.raises(CycleError, match="no cycle with a tensile maximum"):
        from_history(history)
