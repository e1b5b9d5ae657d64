"""Pre-screens for the two detectors of :mod:`.records` that fit a power law
(``find_contact``, ``find_runaway``), and for ``find_late_zero``, across all records at once
(:class:`.blocks.Blocks`).

They sum with BLAS dot products and solve with LAPACK, whose rounding cannot be reproduced
across tests; so the batch code only *screens out* the tests that certainly have no finding
— the test's statistic is computed here in closed form and must lie far (:data:`MARGIN`,
relative) on the clean side of its threshold, in a well-conditioned fit — and the
per-record detector decides every other test, so that a finding's values (contact point,
residual ratio, onset, excess) are always the per-record code's own. Records holding a NaN
or an infinity (possible only in a campaign assembled by hand, not loaded) go to the
per-record detectors outright.
"""

from __future__ import annotations

import numpy as np

from .blocks import Blocks, BoolArray, FloatArray, IntArray, block_quantum, py_max, unfinite
from .records import (
    CONTACT_EARLY_FRACTION,
    CONTACT_LAW_EXCESS,
    CONTACT_NOISE_WIDTHS,
    CONTACT_WEAK_RATIO,
    CONTACT_WEAK_TRAVEL,
    RUNAWAY_EXCESS,
    RUNAWAY_FLAT_GAIN,
    RUNAWAY_MIN_TRAVEL,
)

__all__ = [
    "MARGIN",
    "contact_candidates",
    "contact_statistics",
    "late_zero_candidates",
    "runaway_candidates",
    "runaway_statistics",
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


def _fit_lines(
    blocks: Blocks, x: np.ndarray, y: np.ndarray, w: np.ndarray | None = None
) -> tuple[FloatArray, FloatArray, BoolArray]:
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


def contact_statistics(
    blocks: Blocks, z: np.ndarray, force: np.ndarray
) -> tuple[BoolArray, FloatArray, FloatArray, FloatArray, BoolArray]:
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
    local = blocks.local
    n = blocks.sizes
    alive = n >= 8
    head, hi = blocks.head(3)
    base = head.median(force[hi])
    second, sb = blocks.diff(force, 2)
    centre = sb.median(second)
    with np.errstate(invalid="ignore"):
        mad = sb.median(np.abs(second - sb.spread(centre)))
    noise = py_max(1.4826 * mad / np.sqrt(6.0), block_quantum(blocks, force))
    threshold = base + py_max(CONTACT_NOISE_WIDTHS * noise, 0.01 * (blocks.max(force) - base))
    above = force > blocks.spread(threshold)
    first = blocks.first(_held(blocks, above))
    alive &= first >= 0
    travel = blocks.max(z) - py_max(blocks.min(z), np.zeros(blocks.count))
    free = (local < blocks.spread(first)) & (z > 0)
    alive &= (blocks.total_of(free) >= 3) & (travel > 0)
    z_free = blocks.max(z, where=free)
    alive &= ~(z_free < CONTACT_WEAK_TRAVEL * travel)
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
    best shifted law is clearly (:data:`MARGIN`) worse than :data:`CONTACT_WEAK_RATIO` ×
    the one from z = 0
    and the law from z = 0 stays clearly below :data:`CONTACT_LAW_EXCESS` times the rise
    threshold at the free travel's end, in well-conditioned fits. The per-record detector
    decides the blocks returned.
    """
    with np.errstate(all="ignore"):
        alive, from_zero, coarse, law_excess, trusted = contact_statistics(blocks, z, force)
        clear = (
            trusted
            & (from_zero > 0)
            & (coarse > CONTACT_WEAK_RATIO * from_zero * (1.0 + MARGIN))
            & (law_excess < CONTACT_LAW_EXCESS * (1.0 - MARGIN))
        )
    return np.union1d(np.flatnonzero(alive & ~clear), unfinite(blocks, z, force))


def late_zero_candidates(blocks: Blocks, z: np.ndarray, force: np.ndarray) -> IntArray:
    """The blocks that ``records.find_late_zero`` may find a loading branch at z <= 0 in;
    all others have none.

    A branch is three or more consecutive samples at z <= 0 above the rise threshold,
    base + max(5 noise widths, 1 % of (peak − base)), in a record of 8 samples or more; a
    block is a candidate when it holds three consecutive samples at z <= 0 above
    base + 1 % of (peak − base) alone. Both use the per-record code's numbers exactly (the
    median of the first three forces, the maximum) and rounding is monotone, so the
    threshold is never below that bound: no block with a branch is screened out, and the
    noise width (a median of second differences) is not needed. On a clean record the
    samples at z <= 0 sit at the floor; a seating preload passes this screen and the
    per-record detector decides it.
    """
    if not z.size:
        return np.empty(0, np.int64)
    head, hi = blocks.head(3)
    base = head.median(force[hi])
    with np.errstate(invalid="ignore"):
        bound = base + 0.01 * (blocks.max(force) - base)
        loaded = (z <= 0) & (force > blocks.spread(bound)) & blocks.spread(blocks.sizes >= 8)
    held = _held(blocks, loaded)
    return np.union1d(np.flatnonzero(blocks.total_of(held)), unfinite(blocks, z, force))


def _held(blocks: Blocks, mask: np.ndarray) -> np.ndarray:
    """mask[j] & mask[j+1] & mask[j+2] inside each block: where a condition starts to hold
    for three samples (the detectors' held rise, ``above[:-2] & above[1:-1] & above[2:]``)."""
    block = blocks.block_of
    ahead1 = np.r_[mask[1:], False] & (np.r_[block[1:], -1] == block)
    ahead2 = np.r_[mask[2:], False, False] & (np.r_[block[2:], -1, -1] == block)
    return mask & ahead1 & ahead2


def _power_law_residuals(
    blocks: Blocks, z: np.ndarray, force: np.ndarray, ref: np.ndarray
) -> tuple[FloatArray, BoolArray, FloatArray, FloatArray]:
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
    return np.union1d(np.flatnonzero(undecided | (alive & ~clear)), unfinite(blocks, z, force))


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


def runaway_statistics(
    blocks: Blocks, z: np.ndarray, force: np.ndarray
) -> tuple[BoolArray, FloatArray, BoolArray, BoolArray]:
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
