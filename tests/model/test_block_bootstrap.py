import numpy as np
import pytest

from model.block_bootstrap import BlockPools


def test_blocks_are_consecutive_flights_of_the_pool_wrapping_at_its_end() -> None:
    pool = np.arange(1.0, 6.0)  # 5 flights
    draw = BlockPools.of([pool], seed=3, block_flights=4, n_flights=4_000).draw(0, 4_000)[0]
    blocks = draw.reshape(-1, 4).astype(int) - 1
    assert (np.diff(blocks, axis=1) % 5 == 1).all()  # each block steps through the pool
    assert (blocks[:, 0] == 4).any()  # a block starting at the last flight wraps to the first


def test_block_starts_are_uniform_over_the_pool() -> None:
    pool = np.arange(1.0, 8.0)
    draw = BlockPools.of([pool], seed=1, block_flights=1, n_flights=70_000).draw(5, 70_000)[0]
    counts = np.bincount(draw.astype(int) - 1, minlength=7)
    expected = 70_000 / 7
    chi2 = float(((counts - expected) ** 2 / expected).sum())
    assert chi2 < 22.5  # 6 degrees of freedom: p = 0.001


def test_a_rows_draws_depend_on_its_own_seed_index_and_sample_alone() -> None:
    pools = [np.arange(1.0, 30.0), np.arange(100.0, 110.0)]
    source = BlockPools.of(pools, seed=7, block_flights=2, n_flights=50)
    other = BlockPools.of([np.arange(1.0, 30.0)], seed=8, block_flights=3, n_flights=20)
    stacked = BlockPools.stacked([other, source])
    np.testing.assert_array_equal(stacked.draw(4, 50)[1:], source.draw(4, 50))
    np.testing.assert_array_equal(stacked.draw(4, 50)[0, :20], other.draw(4, 20)[0])
    assert (stacked.draw(4, 50)[0, 20:] == 0).all()
    assert not np.array_equal(source.draw(4, 50), source.draw(5, 50))
    first = BlockPools.of(pools[:1], seed=7, block_flights=2, n_flights=50).draw(4, 50)
    np.testing.assert_array_equal(first[0], source.draw(4, 50)[0])  # index 0 of seed 7 both
    with pytest.raises(ValueError, match="seed"):
        BlockPools.of(pools, seed=-1, block_flights=2, n_flights=5)
    with pytest.raises(ValueError, match="sample"):
        source.draw(-1, 5)
