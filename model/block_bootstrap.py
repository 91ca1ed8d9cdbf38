"""Block-bootstrap draws of many tails' future flights in one compiled pass.

Each row (a tail) has its own pool of recent flights, seed, block length and number of future
flights.  Block j of sample k starts at a uniform flight of the row's pool (circular: a block
may wrap from the last flight to the first), the uniform taken from a counter-based generator
(SplitMix64's output function) keyed by (seed, the row's index within its source, k, j).  So a
row's draws depend on its own key alone: a tail drawn with others gets the future it gets alone,
and sample k of 300 tails is one call, where a numpy generator per tail and sample cost ~5 s of
a 300-tail refill's 60,000 draws (benchmarks/tracking_service.py).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX_1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX_2 = np.uint64(0x94D049BB133111EB)
_TO_UNIT = 2.0**-53


@numba.njit(cache=True, inline="always")
def _mix(z: np.uint64) -> np.uint64:  # pragma: no cover - compiled
    """SplitMix64's finaliser: a bijection of the 64-bit words that scatters every input bit."""
    z = (z ^ (z >> np.uint64(30))) * _MIX_1
    z = (z ^ (z >> np.uint64(27))) * _MIX_2
    return z ^ (z >> np.uint64(31))


@numba.njit(cache=True)
def _row_keys(seeds: np.ndarray, indices: np.ndarray) -> np.ndarray:  # pragma: no cover
    out = np.empty(seeds.shape[0], dtype=np.uint64)
    for r in range(seeds.shape[0]):
        out[r] = _mix(_mix(seeds[r] + _GOLDEN) ^ indices[r])
    return out


@numba.njit(cache=True, nogil=True)
def _draw(
    pool: np.ndarray,
    offsets: np.ndarray,
    lengths: np.ndarray,
    keys: np.ndarray,
    blocks: np.ndarray,
    flights: np.ndarray,
    sample: np.uint64,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    salt = _mix(sample + _GOLDEN)
    for r in range(out.shape[0]):
        state = _mix(keys[r] ^ salt)
        length, block, first = lengths[r], blocks[r], offsets[r]
        t = 0
        while t < flights[r]:
            state += _GOLDEN
            at = int((_mix(state) >> np.uint64(11)) * _TO_UNIT * length)
            for o in range(min(block, flights[r] - t)):
                out[r, t + o] = pool[first + at]
                at = at + 1 if at + 1 < length else 0
            t += block


@dataclass(frozen=True)
class BlockPools:
    """Rows of block-bootstrapped futures: pool (total,) every row's recent stress ranges in MPa,
    concatenated; offsets, lengths (rows,) where each row's pool lies in it; keys (rows,) the
    generator's key of each row; blocks (rows,) flights per block; flights (rows,) future
    flights drawn (zero beyond)."""

    pool: np.ndarray
    offsets: np.ndarray
    lengths: np.ndarray
    keys: np.ndarray
    blocks: np.ndarray
    flights: np.ndarray

    @classmethod
    def of(
        cls,
        pools: Sequence[np.ndarray],
        seed: int,
        block_flights: int,
        n_flights: int,
    ) -> BlockPools:
        """Rows 0..len(pools)-1 of one source: pools[i] is row i's recent flights (non-empty),
        keyed by (seed, i).  Raises ValueError for a negative seed."""
        if seed < 0:
            raise ValueError(f"seed must be >= 0, got {seed}")
        lengths = np.array([len(p) for p in pools], dtype=np.int64)
        rows = len(pools)
        return cls(
            np.concatenate([np.asarray(p, dtype=np.float64) for p in pools]),
            np.concatenate(([0], np.cumsum(lengths)[:-1])).astype(np.int64),
            lengths,
            _row_keys(np.full(rows, seed, dtype=np.uint64), np.arange(rows, dtype=np.uint64)),
            np.full(rows, block_flights, dtype=np.int64),
            np.full(rows, n_flights, dtype=np.int64),
        )

    @classmethod
    def stacked(cls, parts: Sequence[BlockPools]) -> BlockPools:
        """The rows of every part, in order, each keeping its own draws."""
        shift = np.cumsum([0, *(len(p.pool) for p in parts[:-1])])
        return cls(
            np.concatenate([p.pool for p in parts]),
            np.concatenate([p.offsets + s for p, s in zip(parts, shift, strict=True)]),
            *(np.concatenate([getattr(p, f) for p in parts]) for f in _ROW_FIELDS),
        )

    def draw(self, sample: int, n_flights: int) -> np.ndarray:
        """(rows, n_flights) stress ranges of sample `sample`, zero past each row's flights.
        Raises ValueError for sample < 0."""
        if sample < 0:
            raise ValueError(f"sample must be >= 0, got {sample}")
        out = np.zeros((len(self.lengths), n_flights))
        args = (self.pool, self.offsets, self.lengths, self.keys, self.blocks, self.flights)
        _draw(*args, np.uint64(sample), out)
        return out


_ROW_FIELDS = ("lengths", "keys", "blocks", "flights")
