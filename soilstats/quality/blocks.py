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
detectors that fit a power law (``find_contact``, ``find_runaway``) sum with BLAS dot products
and solve with LAPACK, whose rounding cannot be reproduced across tests; for them the batch
code only *screens out* the tests that certainly have no finding — the test's statistic is
computed here in closed form and must lie far (:data:`MARGIN`, relative) on the clean side of
its threshold, in a well-conditioned fit — and the per-record detector decides every other
test, so that a finding's values (contact point, residual ratio, onset, excess) are always
the per-record code's own. Records holding a NaN or an infinity (possible only in a campaign
assembled by hand, not loaded) are screened by the per-record detectors outright.
``tests/test_quality_blocks.py`` checks all this against the per-record detectors on planted
artefacts of every kind.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from . import records
from .records import (
    CONTACT_EARLY_FRACTION,
    CONTACT_LAW_EXCESS,
    CONTACT_MIN_TRAVEL,
    CONTACT_NOISE_WIDTHS,
    FALLBACK_FRACTION,
    FALLBACK_MIN_RUN,
    RUNAWAY_EXCESS,
    RUNAWAY_FLAT_GAIN,
    RUNAWAY_MIN_TRAVEL,
    SATURATION_MIN_SAMPLES,
    SPIKE_MAX_RUN,
    SPIKE_NOISE_WIDTHS,
    SPIKE_SPAN_FRACTION,
)

__all__ = [
    "MARGIN",
    "Blocks",
    "contact_candidates",
    "contact_statistics",
    "non_monotone",
    "runaway_candidates",
    "runaway_statistics",
    "saturation",
    "spikes",
]

#: How far (relative) a closed-form statistic must lie on the clean side of its threshold
#: for a test to be screened out without the per-record detector. The closed form and the
#: per-record code differ by rounding only (at most 2e-11 relative over three simulated
#: 10,000-test campaigns, clean and with planted artefacts); the margin is nine orders of
#: magnitude wider, and costs little: it sends ~1 % of clean tests to the per-record code.
MARGIN = 0.01
#: A least-squares fit counts as well-conditioned when the spread of its abscissae is at
#: least this fraction of their size (centred over raw sum of squares).
_CONDITIONING = 1e-6
#: ... and its residual at least this fraction of the weighted sum of squares, so that
#: rounding in the fitted curve cannot be a sizeable part of the residual.
_RESIDUAL_FLOOR = 1e-10
#: An exponent this close to 0 has no sign one can trust to rounding.
_SIGN_TOLERANCE = 1e-8
#: A generous bound on how far rounding moves a fitted slope or intercept, relative.
_FIT_TOLERANCE = 1e-9

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
    def of_sizes(cls, sizes) -> Blocks:
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

    def reduce(self, ufunc: np.ufunc, values: np.ndarray, empty) -> np.ndarray:
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

    def padded(self, values: np.ndarray, fill: float):
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

    def runs(self, mask: BoolArray) -> tuple[IntArray, IntArray]:
        """(start, stop) positions of each run of True, runs never crossing a block edge."""
        if not mask.size:
            return np.empty(0, np.int64), np.empty(0, np.int64)
        block = self.block_of
        before = np.r_[False, mask[:-1] & (block[1:] == block[:-1])]
        after = np.r_[mask[1:] & (block[1:] == block[:-1]), False]
        return np.flatnonzero(mask & ~before), np.flatnonzero(mask & ~after) + 1


def _runs_mask(blocks: Blocks, mask: BoolArray, keep) -> BoolArray:
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


def _quantum(blocks: Blocks, values: np.ndarray) -> FloatArray:
    """``records._quantum`` of every block: the sensor's step, or 0 (repeats on a plateau
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


def _py_max(*values: np.ndarray) -> np.ndarray:
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
    width = _py_max(1.4826 * sb.median(second), _quantum(blocks, values), 1e-9 * span)
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
    # along (records._drop_dragged): the few records holding such a group are judged by
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


def _unfinite(blocks: Blocks, *arrays: np.ndarray) -> IntArray:
    """The blocks holding a value that is not finite (NaN, ±inf)."""
    bad = np.zeros(blocks.total, dtype=bool)
    for values in arrays:
        bad |= ~np.isfinite(values)
    return np.flatnonzero(blocks.total_of(bad)) if bad.any() else np.empty(0, np.int64)


def _by_record(blocks: Blocks, batch, detector, *arrays: np.ndarray) -> BoolArray:
    """``batch(blocks, *arrays)``, with the blocks holding non-finite values decided by the
    per-record ``detector`` instead.

    A validated campaign has only finite samples; a campaign assembled by hand may not, and
    sorting networks and np.median treat NaN differently, so such records keep exactly the
    per-record behaviour rather than a batch imitation of it.
    """
    with np.errstate(all="ignore"):  # NaN blocks may warn here; they are redone below
        mask = batch(blocks, *arrays)
    for k in _unfinite(blocks, *arrays):
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


def _fit_lines(blocks: Blocks, x: np.ndarray, y: np.ndarray, w: np.ndarray | None = None):
    """Weighted least-squares lines y ≈ a + b x of every block, in closed form.

    Centred sums (two passes) keep them accurate. Returns (slope, intercept, conditioned):
    ``conditioned`` is False where the abscissae barely spread (the fit is then left to the
    per-record code).
    """
    w = np.ones_like(x) if w is None else w
    sw = blocks.reduce(np.add, w, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mx = blocks.reduce(np.add, w * x, 0.0) / sw
        my = blocks.reduce(np.add, w * y, 0.0) / sw
        dx = x - blocks.spread(mx)
        dy = y - blocks.spread(my)
        sxx = blocks.reduce(np.add, w * dx * dx, 0.0)
        sxy = blocks.reduce(np.add, w * dx * dy, 0.0)
        size = blocks.reduce(np.add, w * x * x, 0.0)
        slope = sxy / sxx
        intercept = my - slope * mx
        conditioned = (sw > 0) & (sxx > _CONDITIONING * size) & np.isfinite(slope)
    return slope, intercept, conditioned


def contact_statistics(blocks: Blocks, z: np.ndarray, force: np.ndarray):
    """What ``records.find_contact`` compares, for every block: (alive, from_zero, coarse,
    law_excess, trusted). ``alive``: the block passed the detector's exact early exits;
    ``from_zero`` and ``coarse``: the residual of the power law from z = 0 and the least
    residual over the grid of contact points (closed form); ``law_excess``:
    the law from z = 0 at the deepest free sample over the rise threshold; ``trusted``: all
    are accurate to :data:`MARGIN`."""
    empty = np.zeros(blocks.count, dtype=bool)
    if not z.size:
        nothing = np.full(blocks.count, np.inf)
        return empty, nothing, nothing.copy(), np.full(blocks.count, np.nan), empty
    block = blocks.block_of
    local = blocks.local
    n = blocks.sizes
    alive = n >= 8
    head, hi = blocks.head(3)
    base = head.median(force[hi])
    second, sb = blocks.diff(force, 2)
    centre = sb.median(second)
    with np.errstate(invalid="ignore"):
        mad = sb.median(np.abs(second - sb.spread(centre)))
    noise = _py_max(1.4826 * mad / np.sqrt(6.0), _quantum(blocks, force))
    threshold = base + _py_max(CONTACT_NOISE_WIDTHS * noise, 0.01 * (blocks.max(force) - base))
    above = force > blocks.spread(threshold)
    # rising[j] = above[j] & above[j+1] & above[j+2], inside the block
    ahead1 = np.r_[above[1:], False] & (np.r_[block[1:], -1] == block)
    ahead2 = np.r_[above[2:], False, False] & (np.r_[block[2:], -1, -1] == block)
    first = blocks.first(above & ahead1 & ahead2)
    alive &= first >= 0
    travel = blocks.max(z) - _py_max(blocks.min(z), np.zeros(blocks.count))
    free = (local < blocks.spread(first)) & (z > 0)
    alive &= (blocks.total_of(free) >= 3) & (travel > 0)
    z_free = blocks.max(z, where=free)
    alive &= ~(z_free < CONTACT_MIN_TRAVEL * travel)
    # The loaded part of the surviving blocks, for the power-law comparison.
    loaded = blocks.spread(alive) & (local >= blocks.spread(first))
    lb, li = blocks.keep(loaded)
    zl = z[li]
    fl = force[li] - lb.spread(base)
    upper = lb.min(zl, where=zl > 0)
    alive &= np.isfinite(upper) & (upper > 0)
    zero = np.zeros(blocks.count)
    from_zero, trusted, _, _ = _power_law_residuals(lb, zl, fl, zero)
    # The early law from z = 0 (records.find_contact): up to CONTACT_EARLY_FRACTION of the
    # loaded record's peak, at least four samples.
    reach = lb.first(fl >= lb.spread(CONTACT_EARLY_FRACTION * lb.max(fl)))
    stop = np.maximum(np.where(reach >= 0, reach, lb.sizes), 3)
    eb, ei = lb.keep(lb.local <= lb.spread(stop))
    _, early_ok, n0, log_k0 = _power_law_residuals(eb, zl[ei], fl[ei], zero)
    trusted &= alive & early_ok
    refs = np.linspace(0.0, 1.0, 12, endpoint=False)[1:]
    residual = np.full((blocks.count, refs.size), np.inf)
    for r, step in enumerate(refs):
        ref = np.where(np.isfinite(upper), upper, 0.0) * step
        res, ok, _, _ = _power_law_residuals(lb, zl, fl, ref)
        residual[:, r] = res
        trusted &= ok
    with np.errstate(all="ignore"):
        last_free = blocks.starts + np.maximum(_last(blocks, free, local), 0)
        z_last = z[np.minimum(last_free, max(blocks.total - 1, 0))] if z.size else zero
        law_excess = np.exp(log_k0 + n0 * np.log(z_last)) / (threshold - base)
    return alive, from_zero, residual.min(axis=1), law_excess, trusted


def contact_candidates(blocks: Blocks, z: np.ndarray, force: np.ndarray) -> IntArray:
    """The blocks that ``records.find_contact`` may find a contact in; all others have none.

    The cheap exits of the per-record detector (no rise above the noise floor, no material
    free travel, nothing loaded) are taken here exactly; the power-law
    comparisons are made in closed form, and a block is screened out only when even the
    best shifted law is clearly (:data:`MARGIN`) worse than ``0.8 ×`` the one from z = 0
    and the law from z = 0 stays clearly below :data:`CONTACT_LAW_EXCESS` times the rise
    threshold at the free travel's end, in well-conditioned fits. The per-record detector
    decides the blocks returned.
    """
    with np.errstate(all="ignore"):
        alive, from_zero, coarse, law_excess, trusted = contact_statistics(blocks, z, force)
        clear = (
            trusted
            & (from_zero > 0)
            & (coarse > 0.8 * from_zero * (1.0 + MARGIN))
            & (law_excess < CONTACT_LAW_EXCESS * (1.0 - MARGIN))
        )
    return np.union1d(np.flatnonzero(alive & ~clear), _unfinite(blocks, z, force))


def _power_law_residuals(
    blocks: Blocks, z: np.ndarray, force: np.ndarray, ref: np.ndarray
) -> tuple[FloatArray, BoolArray]:
    """``records._power_law(z, force, ref)`` of every block, in closed form: (residual,
    whether it can be trusted to :data:`MARGIN` (enough samples, well-conditioned, a residual
    that is not mere rounding), n, ln k)."""
    depth = z - blocks.spread(ref)
    use = (depth > 0) & (force > 0)
    ub, ui = blocks.keep(use)
    f = force[ui]
    x, y, w = np.log(depth[ui]), np.log(f), f * f
    n, log_k, conditioned = _fit_lines(ub, x, y, w)
    model = np.exp(ub.spread(log_k) + ub.spread(n) * x)
    residual = ub.reduce(np.add, (f - model) ** 2, 0.0)
    weight = ub.reduce(np.add, w, 0.0)
    enough = ub.sizes >= 3
    residual = np.where(enough, residual, np.inf)
    with np.errstate(invalid="ignore"):
        trusted = ~enough | (
            conditioned & np.isfinite(residual) & (residual > _RESIDUAL_FLOOR * weight)
        )
    return residual, trusted, n, log_k


def runaway_candidates(blocks: Blocks, z: np.ndarray, force: np.ndarray) -> IntArray:
    """The blocks that ``records.find_runaway`` may find bearing failure in; all others have
    none.

    The early power law is fitted in closed form; a block is screened out when its final
    excess sinkage is clearly (:data:`MARGIN`) below :data:`RUNAWAY_EXCESS`, in a
    well-conditioned fit whose rounding cannot move it that far, and its force is not flat
    at the end (:data:`RUNAWAY_FLAT_GAIN`, computed exactly). The per-record detector
    decides the blocks returned.
    """
    with np.errstate(all="ignore"):
        alive, excess, safe, undecided = runaway_statistics(blocks, z, force)
        gain = _end_gain(blocks, z, force)
        clear = safe & (excess < RUNAWAY_EXCESS * (1.0 - MARGIN)) & ~(gain < RUNAWAY_FLAT_GAIN)
    return np.union1d(np.flatnonzero(undecided | (alive & ~clear)), _unfinite(blocks, z, force))


def _runaway_force(blocks: Blocks, force: np.ndarray) -> FloatArray:
    """The force ``records.find_runaway`` reads: the running median of five, less the start
    level where that is a sensor offset (under 2 % of the peak), every block."""
    f = blocks.rolling_median5(force)
    head, hi = blocks.head(3)
    start = head.median(force[hi])
    with np.errstate(invalid="ignore"):
        shift = np.abs(start) < 0.02 * np.abs(blocks.max(f))
    return f - blocks.spread(np.where(shift, start, 0.0))


def _end_gain(blocks: Blocks, z: np.ndarray, force: np.ndarray) -> FloatArray:
    """``records.find_runaway``'s force gain over the last RUNAWAY_MIN_TRAVEL of the final
    sinkage, every block (the same elementwise steps: exact); NaN where it has no loaded
    sample."""
    if not z.size:
        return np.full(blocks.count, np.nan)
    local = blocks.local
    f = _runaway_force(blocks, force)
    last = _last(blocks, f > 0, local)
    has = last >= 0
    at = np.minimum(blocks.starts + np.maximum(last, 0), blocks.total - 1)
    z_end = np.where(has, z[at], np.nan)
    tail = blocks.first(z >= blocks.spread((1 - RUNAWAY_MIN_TRAVEL) * z_end))
    tail_at = np.minimum(blocks.starts + np.maximum(tail, 0), blocks.total - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        gain = np.where(f[tail_at] > 0, f[at] / f[tail_at] - 1, np.inf)
    return np.where(has & (tail >= 0), gain, np.nan)


def runaway_statistics(blocks: Blocks, z: np.ndarray, force: np.ndarray):
    """What ``records.find_runaway`` compares, for every block: (alive, excess, safe,
    undecided). ``alive``: the block passed the detector's exact early exits with a clearly
    positive exponent; ``excess``: its final excess sinkage (closed-form fit); ``safe``: the
    excess is accurate to :data:`MARGIN`; ``undecided``: the exponent's sign or the fit's
    conditioning is in doubt."""
    empty = np.zeros(blocks.count, dtype=bool)
    if not z.size:
        return empty, np.full(blocks.count, np.nan), empty, empty
    local = blocks.local
    alive = blocks.sizes >= 8
    f = _runaway_force(blocks, force)
    peak = blocks.max(f)
    alive &= peak > 0
    reach = blocks.first(f >= blocks.spread(0.35 * peak))
    early = (z > 0) & (local <= blocks.spread(reach)) & (f > blocks.spread(0.05 * peak))
    early &= blocks.spread(alive)
    eb, ei = blocks.keep(early)
    x, y = np.log(z[ei]), np.log(f[ei])
    alive &= (eb.sizes >= 4) & (eb.max(x) - eb.min(x) > 0)
    n, log_k, conditioned = _fit_lines(eb, x, y)
    undecided = alive & ~conditioned
    # The exponent's sign must be clear: n <= 0 has no finding, an n within rounding of 0
    # is left to the per-record code.
    with np.errstate(invalid="ignore"):
        negative = n < -_SIGN_TOLERANCE
        positive = n > _SIGN_TOLERANCE
    undecided |= alive & conditioned & ~negative & ~positive
    alive &= conditioned & positive
    # The excess at the last loaded sample (the per-record ratio at its last finite value).
    loaded = (f > 0) & blocks.spread(alive)
    last = _last(blocks, loaded, local)
    has = last >= 0
    at = np.minimum(blocks.starts + np.maximum(last, 0), max(blocks.total - 1, 0))
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        exponent = (np.log(np.where(has, f[at], 1.0)) - log_k) / n
        excess = z[at] / np.exp(exponent)
        # Rounding of n and log k (far below _FIT_TOLERANCE of their size) moves the
        # exponent by at most this; beyond exp's range, or without a loaded sample, the
        # block is left to the per-record code.
        shaky = _FIT_TOLERANCE * (1 + np.abs(log_k) + np.abs(exponent) * (1 + n)) / n
    safe = has & (np.abs(exponent) < 600.0) & np.isfinite(excess) & (shaky < MARGIN / 10)
    return alive, excess, safe, undecided


def _last(blocks: Blocks, mask: BoolArray, local: IntArray) -> IntArray:
    """Local position of the last True of every block, -1 where there is none."""
    return blocks.reduce(np.maximum, np.where(mask, local, -1), -1)
