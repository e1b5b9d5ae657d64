"""The records of many tests at once: the detectors of :mod:`.records`, across tests.

A campaign of 10,000 tests holds about a million samples in records of ~100; running the
per-record detectors one test at a time costs ~50 numpy calls per test, so a screening took
seconds of call overhead. Here every record is laid end to end (:class:`Blocks`, one block
per test, in record order) and each step runs once over all of them, with every window,
difference and reduction kept inside its block.

**The results are those of :mod:`.records`, bit for bit.** Every step that decides a flag is
computed with the same floating-point operations as the per-record code: medians are the
middle values of the same numbers (and the mean of the two middle ones, as ``np.median``),
maxima, minima, comparisons and elementwise arithmetic are exact whatever the layout. The two
detectors that fit a power law (``find_contact``, ``find_runaway``) are only pre-screened
across tests (:mod:`.prescreen`). ``tests/test_quality_blocks.py`` checks all this against
the per-record detectors on planted artefacts of every kind.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

from . import records
from .records import FALLBACK_FRACTION, FALLBACK_MIN_RUN, SATURATION_MIN_SAMPLES
from .spikes import SPIKE_MAX_RUN, SPIKE_NOISE_WIDTHS, SPIKE_SPAN_FRACTION

__all__ = ["Blocks", "non_monotone", "saturation", "spikes"]

IntArray = np.ndarray
BoolArray = np.ndarray
FloatArray = np.ndarray


@dataclass(frozen=True)
class Blocks:
    """Records laid end to end: block ``k`` is positions ``starts[k]:starts[k] + sizes[k]``.

    Blocks are contiguous, in order, and cover the whole array (empty blocks allowed).
    """

    starts: IntArray
    sizes: IntArray

    @classmethod
    def of_sizes(cls, sizes: ArrayLike) -> Blocks:
        """Blocks of the given sizes, laid end to end from position 0."""
        sizes = np.asarray(sizes, dtype=np.int64)
        starts = np.zeros(sizes.size, dtype=np.int64)
        np.cumsum(sizes[:-1], out=starts[1:])
        return cls(starts, sizes)

    @property
    def count(self) -> int:
        """Number of blocks."""
        return int(self.sizes.size)

    @property
    def total(self) -> int:
        """Number of positions."""
        return int(self.sizes.sum())

    @cached_property
    def block_of(self) -> IntArray:
        """The block of every position."""
        return np.repeat(np.arange(self.count), self.sizes)

    @cached_property
    def local(self) -> IntArray:
        """The position of every position inside its block (0-based)."""
        return np.arange(self.total) - self.starts[self.block_of]

    def spread(self, per_block: np.ndarray) -> np.ndarray:
        """A per-block value repeated at every position of the block."""
        return np.repeat(per_block, self.sizes)

    def keep(self, mask: BoolArray) -> tuple[Blocks, IntArray]:
        """The blocks of the positions where ``mask`` holds, and those positions."""
        return Blocks.of_sizes(self.total_of(mask)), np.flatnonzero(mask)

    def head(self, n: int) -> tuple[Blocks, IntArray]:
        """Blocks of the first ``n`` positions of every block (or all, when shorter)."""
        local = self.local
        return self.keep(local < n)

    def drop_last(self, k: int) -> tuple[Blocks, IntArray]:
        """Blocks without their last ``k`` positions (empty when not longer than ``k``)."""
        local = self.local
        return self.keep(local < self.spread(self.sizes) - k)

    def reduce(self, ufunc: np.ufunc, values: np.ndarray, empty: float) -> np.ndarray:
        """``ufunc.reduce`` over every block; ``empty`` for empty blocks."""
        out = np.full(self.count, empty, dtype=np.result_type(values, type(empty)))
        full = self.sizes > 0
        if full.any():
            # reduceat over the starts of the non-empty blocks: each runs to the next start.
            out[full] = ufunc.reduceat(values, self.starts[full])
        return out

    def max(self, values: np.ndarray, where: BoolArray | None = None) -> FloatArray:
        """Maximum per block (over ``where`` only); -inf where there is none."""
        if where is not None:
            values = np.where(where, values, -np.inf)
        return self.reduce(np.maximum, values, -np.inf)

    def min(self, values: np.ndarray, where: BoolArray | None = None) -> FloatArray:
        """Minimum per block (over ``where`` only); +inf where there is none."""
        if where is not None:
            values = np.where(where, values, np.inf)
        return self.reduce(np.minimum, values, np.inf)

    def total_of(self, mask: BoolArray) -> IntArray:
        """How many positions of each block ``mask`` holds at."""
        return self.reduce(np.add, mask.astype(np.int64), 0)

    def first(self, mask: BoolArray) -> IntArray:
        """Local position of the first True of every block, -1 where there is none."""
        local = self.local
        hit = np.where(mask, local, np.iinfo(np.int64).max)
        first = self.reduce(np.minimum, hit, np.iinfo(np.int64).max)
        return np.where(first == np.iinfo(np.int64).max, -1, first)

    def diff(self, values: np.ndarray, order: int = 1) -> tuple[np.ndarray, Blocks]:
        """``np.diff(record, order)`` of every block, and their blocks (size n - order)."""
        out, blocks = values, self
        for _ in range(order):
            # diff of diff, as np.diff does: the same subtractions in the same order.
            step = out[1:] - out[:-1]
            blocks, kept = blocks.drop_last(1)
            out = step[kept] if kept.size else np.empty(0)
        return out, blocks

    def padded(
        self, values: np.ndarray, fill: float
    ) -> Iterator[tuple[IntArray, BoolArray, IntArray, FloatArray]]:
        """The non-empty blocks as rows of matrices, in buckets of similar size (the same bit
        length: within a factor two, so padding at most doubles the work).

        Yields ``(rows, valid, index, matrix)`` per bucket: the blocks' numbers, a mask of the
        real entries, their positions in ``values`` (meaningful where valid) and the values,
        ``fill`` beyond each block's end — for an operation along rows that ``fill`` does not
        disturb (a sort with +inf, a running maximum with -inf).
        """
        full = np.flatnonzero(self.sizes > 0)
        bucket = np.frexp(self.sizes[full].astype(np.float64))[1]  # bit length of the size
        for b in np.unique(bucket):
            rows = full[bucket == b]
            sizes = self.sizes[rows]
            cols = np.arange(int(sizes.max()))
            valid = cols[None, :] < sizes[:, None]
            index = self.starts[rows][:, None] + cols[None, :]
            yield rows, valid, index, np.where(valid, values[np.where(valid, index, 0)], fill)

    def median(self, values: np.ndarray) -> FloatArray:
        """``np.median`` of every block (NaN for an empty block).

        Blocks of similar size are sorted together as the rows of a matrix padded with +inf
        (:meth:`padded`); the median is the middle value, or the mean of the two middle
        values, exactly as ``np.median``.
        """
        out = np.full(self.count, np.nan)
        for rows, _, _, matrix in self.padded(values, np.inf):
            sizes = self.sizes[rows]
            matrix.sort(axis=1)
            r = np.arange(rows.size)
            low = matrix[r, (sizes - 1) // 2]
            high = matrix[r, sizes // 2]
            with np.errstate(over="ignore"):
                out[rows] = np.where(sizes % 2 == 1, low, (low + high) / 2.0)
        return out

    def rolling_median5(self, values: np.ndarray) -> FloatArray:
        """``scipy.ndimage.median_filter(record, size=5, mode="nearest")`` of every block.

        Every block is padded with two copies of its edge values (``nearest``), then the
        median of each five neighbours is picked by a min/max network; it is one of the five
        values, so the result is the filter's exactly.
        """
        if not self.total:
            return np.empty(0)
        padded_sizes = np.where(self.sizes > 0, self.sizes + 4, 0)
        padded = Blocks.of_sizes(padded_sizes)
        local = padded.local - 2
        np.clip(local, 0, padded.spread(self.sizes - 1), out=local)
        p = values[local + padded.spread(self.starts)]
        a, b, c, d, e = p[:-4], p[1:-3], p[2:-2], p[3:-1], p[4:]
        # The median of five is the median of c and of the two middle values of the pairs
        # (a, b) and (d, e): the larger of the smaller ones, the smaller of the larger ones.
        low = np.maximum(np.minimum(a, b), np.minimum(d, e))
        high = np.minimum(np.maximum(a, b), np.maximum(d, e))
        median = np.maximum(np.minimum(c, low), np.minimum(np.maximum(c, low), high))
        # The window of a block's position i starts at its padded position i.
        return median[padded.starts[self.block_of] + self.local]

    def rolling_median(self, values: np.ndarray, size: int, chunk: int = 200_000) -> FloatArray:
        """``scipy.ndimage.median_filter(record, size, mode="nearest")`` of every block, for
        an odd ``size``: each position's window of edge-padded neighbours is gathered and its
        middle value picked (``np.partition``), so the result is the filter's exactly.
        Positions go ``chunk`` at a time (memory: chunk × size values)."""
        if not self.total:
            return np.empty(0)
        half = size // 2
        offsets = np.arange(-half, half + 1)
        local, block = self.local, self.block_of
        out = np.empty(self.total)
        for a in range(0, self.total, chunk):
            b = min(a + chunk, self.total)
            last = self.sizes[block[a:b]] - 1
            at = np.clip(local[a:b, None] + offsets[None, :], 0, last[:, None])
            windows = values[at + self.starts[block[a:b]][:, None]]
            out[a:b] = np.partition(windows, half, axis=1)[:, half]
        return out

    def runs(self, mask: BoolArray) -> tuple[IntArray, IntArray]:
        """(start, stop) positions of each run of True, runs never crossing a block edge."""
        if not mask.size:
            return np.empty(0, np.int64), np.empty(0, np.int64)
        block = self.block_of
        before = np.r_[False, mask[:-1] & (block[1:] == block[:-1])]
        after = np.r_[mask[1:] & (block[1:] == block[:-1]), False]
        return np.flatnonzero(mask & ~before), np.flatnonzero(mask & ~after) + 1


def _runs_mask(blocks: Blocks, mask: BoolArray, keep: Callable[[IntArray], BoolArray]) -> BoolArray:
    """``mask`` restricted to its runs whose length passes ``keep(length)``."""
    start, stop = blocks.runs(mask)
    chosen = keep(stop - start)
    out = np.zeros(mask.size, dtype=bool)
    if chosen.any():
        # Mark +1 at each chosen run's start and -1 at its stop; the running sum is the mask.
        edges = np.zeros(mask.size + 1, dtype=np.int64)
        np.add.at(edges, start[chosen], 1)
        np.add.at(edges, stop[chosen], -1)
        out = np.cumsum(edges[:-1]) > 0
    return out


def block_quantum(blocks: Blocks, values: np.ndarray) -> FloatArray:
    """``noise.quantum`` of every block: the sensor's step, or 0 (repeats on a plateau
    at the block's maximum not counted)."""
    sb, kept = blocks.drop_last(1)
    steps = np.abs(values[kept + 1] - values[kept]) if kept.size else np.empty(0)
    top = values == blocks.spread(blocks.max(values))
    plateau = top[kept] & top[kept + 1] if kept.size else np.zeros(0, dtype=bool)
    n = sb.sizes - sb.total_of(plateau)
    zeros = sb.total_of((steps == 0) & ~plateau)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = zeros.astype(np.float64) / n  # np.mean of a bool array: count / size
    smallest = sb.min(steps, where=steps > 0)
    quantised = (n > 0) & ~(share < 0.1) & np.isfinite(smallest)
    return np.where(quantised, smallest, 0.0)


def py_max(*values: np.ndarray) -> np.ndarray:
    """Elementwise ``max(a, b, ...)`` with Python's tie rule (the first of equal values)."""
    out = values[0]
    for v in values[1:]:
        out = np.where(v > out, v, out)
    return out


def _spikes(blocks: Blocks, values: np.ndarray) -> BoolArray:
    out = np.zeros(values.size, dtype=bool)
    if not values.size:
        return out
    block = blocks.block_of
    smooth = blocks.rolling_median5(values)
    departure = np.abs(values - smooth)
    span = blocks.max(smooth) - blocks.min(smooth)
    judged = (blocks.sizes >= 5) & (span > 0)
    second, sb = blocks.diff(values, 2)
    second = np.abs(second) / np.sqrt(6.0)
    width = py_max(1.4826 * sb.median(second), block_quantum(blocks, values), 1e-9 * span)
    off = (
        blocks.spread(judged)
        & (departure > SPIKE_NOISE_WIDTHS * blocks.spread(width))
        & (departure > SPIKE_SPAN_FRACTION * blocks.spread(span))
    )
    # The few candidates are judged against their local noise too (21 samples around each),
    # one by one with np.median as the per-record code does.
    local = blocks.local
    for i in np.flatnonzero(off):
        k, j = block[i], local[i]
        n = blocks.sizes[k]
        # records: padded = np.pad(second, 1, mode="edge"); padded[max(0, j-10) : j+11]
        window = np.clip(np.arange(max(0, j - 10), min(n, j + 11)) - 1, 0, n - 3)
        noise = 1.4826 * float(np.median(second[sb.starts[k] + window]))
        off[i] = departure[i] > SPIKE_NOISE_WIDTHS * noise
    out = _runs_mask(blocks, off, lambda length: length <= SPIKE_MAX_RUN)
    # Off samples within 2 of each other may be one spike dragging its neighbours' medians
    # along (spikes.drop_dragged): the few records holding such a group are judged by
    # the per-record code.
    at = np.flatnonzero(off)
    near = (np.diff(at) <= 2) & (block[at[1:]] == block[at[:-1]])
    for k in np.unique(block[at[1:][near]]):
        record = slice(blocks.starts[k], blocks.starts[k] + blocks.sizes[k])
        out[record] = False
        out[blocks.starts[k] + records.find_spikes(values[record].copy())] = True
    return out


def _non_monotone(blocks: Blocks, z: np.ndarray) -> BoolArray:
    if not z.size:
        return np.zeros(0, dtype=bool)
    travel = blocks.max(z) - blocks.min(z)
    judged = (blocks.sizes >= FALLBACK_MIN_RUN + 1) & (travel > 0)
    running = _running_max(blocks, z)
    fallen = blocks.spread(judged) & ((running - z) > FALLBACK_FRACTION * blocks.spread(travel))
    return _runs_mask(blocks, fallen, lambda length: length >= FALLBACK_MIN_RUN)


def _running_max(blocks: Blocks, values: np.ndarray) -> FloatArray:
    """``np.maximum.accumulate`` inside every block (a maximum never crosses a block edge).

    Blocks of similar size are accumulated together as the rows of a matrix padded at the
    end with -inf (:meth:`Blocks.padded`; no running maximum of the real values reaches it).
    """
    out = np.empty_like(values)
    for _, valid, index, matrix in blocks.padded(values, -np.inf):
        out[index[valid]] = np.maximum.accumulate(matrix, axis=1)[valid]
    return out


def _saturation(blocks: Blocks, values: np.ndarray, other: np.ndarray) -> BoolArray:
    if not values.size:
        return np.zeros(0, dtype=bool)
    at_max = values == blocks.spread(blocks.max(values))
    span = blocks.max(other) - blocks.min(other)
    spread_at_max = blocks.max(other, where=at_max) - blocks.min(other, where=at_max)
    clipped = (
        (blocks.total_of(at_max) >= SATURATION_MIN_SAMPLES)
        & (span > 0)
        & ~(spread_at_max <= 0.01 * span)
    )
    return at_max & blocks.spread(clipped)


def unfinite(blocks: Blocks, *arrays: np.ndarray) -> IntArray:
    """The blocks holding a value that is not finite (NaN, ±inf)."""
    bad = np.zeros(blocks.total, dtype=bool)
    for values in arrays:
        bad |= ~np.isfinite(values)
    return np.flatnonzero(blocks.total_of(bad)) if bad.any() else np.empty(0, np.int64)


def _by_record(
    blocks: Blocks,
    batch: Callable[..., BoolArray],
    detector: Callable[..., BoolArray],
    *arrays: np.ndarray,
) -> BoolArray:
    """``batch(blocks, *arrays)``, with the blocks holding non-finite values decided by the
    per-record ``detector`` instead.

    A validated campaign has only finite samples; a campaign assembled by hand may not, and
    sorting networks and np.median treat NaN differently, so such records keep exactly the
    per-record behaviour rather than a batch imitation of it.
    """
    with np.errstate(all="ignore"):  # NaN blocks may warn here; they are redone below
        mask = batch(blocks, *arrays)
    for k in unfinite(blocks, *arrays):
        at = slice(blocks.starts[k], blocks.starts[k] + blocks.sizes[k])
        mask[at] = False
        mask[blocks.starts[k] + detector(*(a[at].copy() for a in arrays))] = True
    return mask


def spikes(blocks: Blocks, values: np.ndarray) -> BoolArray:
    """``records.find_spikes`` of every block, as a mask over the positions."""
    return _by_record(blocks, _spikes, records.find_spikes, values)


def non_monotone(blocks: Blocks, z: np.ndarray) -> BoolArray:
    """``records.find_non_monotone`` of every block, as a mask over the positions."""
    return _by_record(blocks, _non_monotone, records.find_non_monotone, z)


def saturation(blocks: Blocks, values: np.ndarray, other: np.ndarray) -> BoolArray:
    """``records.find_saturation(values, other)`` of every block, as a mask."""
    return _by_record(blocks, _saturation, records.find_saturation, values, other)
