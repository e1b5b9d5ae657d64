"""Detectors on one test's record (numpy arrays in record order; no campaign, no pandas).

Each returns what it found as positions in the record; :mod:`.screen` turns them into flags.
Every threshold is a named constant here, chosen so that clean simulated records (white
force noise, quantised sensors, exponents 0.3-2) are never flagged — ``tests/test_quality.py``
checks that over many seeds — while the artefacts of real records are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import median_filter
from scipy.optimize import minimize_scalar

__all__ = [
    "ContactPoint",
    "Runaway",
    "find_contact",
    "find_non_monotone",
    "find_runaway",
    "find_saturation",
    "find_spikes",
]

#: Spikes: departure from the running median (width 5) in robust noise widths ...
SPIKE_NOISE_WIDTHS = 10.0
#: ... and as a fraction of the test's span (smaller glitches do not move a fit).
SPIKE_SPAN_FRACTION = 0.05
#: A run longer than this is a feature of the record, not a spike.
SPIKE_MAX_RUN = 2
#: Pre-contact: the force threshold above the starting baseline, in noise widths ...
CONTACT_NOISE_WIDTHS = 5.0
#: ... the free travel that matters, as a fraction of the test's travel ...
CONTACT_MIN_TRAVEL = 0.02
#: ... and how much better (residual ratio) a power law from the contact must fit.
CONTACT_RESIDUAL_RATIO = 0.5
#: A record whose first samples carry more than this share of its peak force (and more than
#: CONTACT_NOISE_WIDTHS noise widths) started under load (a seating preload, a record cut
#: after contact): no pre-contact segment is sought.
CONTACT_MAX_START = 0.05
#: Runaway: how many times deeper than the early law the record may end ...
RUNAWAY_EXCESS = 2.0
#: ... the departure from the early law that marks the onset ...
RUNAWAY_ONSET = 1.25
#: ... and the least excess travel, as a fraction of the final sinkage.
RUNAWAY_MIN_TRAVEL = 0.25
#: Non-monotone: a fall below the running maximum, as a fraction of the travel ...
FALLBACK_FRACTION = 0.02
#: ... lasting this many samples at least (shorter is a spike's business).
FALLBACK_MIN_RUN = 3
#: Saturation: samples exactly at the maximum.
SATURATION_MIN_SAMPLES = 4


def _robust_width(values: np.ndarray) -> float:
    """1.4826 × median absolute deviation: the standard deviation of Gaussian noise."""
    if values.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(values - np.median(values))))


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) of each run of True in ``mask``."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _quantum(values: np.ndarray) -> float:
    """The sensor's step where the record is visibly quantised (≥ 10 % repeated readings),
    else 0: on a sparse record the smallest change is the signal's, not the sensor's."""
    steps = np.abs(np.diff(values))
    if steps.size == 0 or np.mean(steps == 0) < 0.1:
        return 0.0
    steps = steps[steps > 0]
    return float(steps.min()) if steps.size else 0.0


def find_spikes(values: np.ndarray) -> np.ndarray:
    """Positions of isolated spikes (runs of at most :data:`SPIKE_MAX_RUN` samples).

    A sample is off when it departs from the running median of five by more than
    :data:`SPIKE_NOISE_WIDTHS` robust noise widths — the larger of the record's and the local
    one over 21 samples (noise grows with the load), floored at the sensor's step — and by
    more than :data:`SPIKE_SPAN_FRACTION` of the median-filtered span. The median of five follows
    steps and monotone ramps exactly, so runaway sinkage and steep loading are never spikes.
    """
    x = np.asarray(values, float)
    if x.size < 5:
        return np.array([], int)
    smooth = median_filter(x, size=5, mode="nearest")
    departure = x - smooth
    span = float(smooth.max() - smooth.min())
    if span <= 0:
        return np.array([], int)
    # Noise from second differences (blind to ramps and curvature; white noise: sqrt(6) σ).
    second = np.abs(np.diff(x, 2)) / np.sqrt(6.0)
    width = max(1.4826 * float(np.median(second)), _quantum(x), 1e-9 * span)
    off = (np.abs(departure) > SPIKE_NOISE_WIDTHS * width) & (
        np.abs(departure) > SPIKE_SPAN_FRACTION * span
    )
    if not off.any():
        return np.array([], int)
    # Judge the few candidates against their local noise too (21 samples around each).
    padded = np.pad(second, 1, mode="edge")
    for i in np.flatnonzero(off):
        local = 1.4826 * float(np.median(padded[max(0, i - 10) : i + 11]))
        off[i] = abs(departure[i]) > SPIKE_NOISE_WIDTHS * local
    keep = [np.arange(a, b) for a, b in _runs(off) if b - a <= SPIKE_MAX_RUN]
    return np.concatenate(keep) if keep else np.array([], int)


def _power_law_residual(z: np.ndarray, force: np.ndarray, z_ref: float) -> float:
    """Residual sum of squares of force ≈ k (z − z_ref)^n fitted by p²-weighted log–log
    least squares (Wong's weighting), on the samples with z > z_ref and force > 0."""
    depth = z - z_ref
    use = (depth > 0) & (force > 0)
    if use.sum() < 3:
        return np.inf
    f = force[use]
    x, y, w = np.log(depth[use]), np.log(f), f * f
    # The 2 × 2 weighted normal equations in closed form (called ~30 times per record).
    sw, sx, sy = w.sum(), w @ x, w @ y
    sxx, sxy = w @ (x * x), w @ (x * y)
    det = sw * sxx - sx * sx
    if det <= 0:
        return np.inf
    n = (sw * sxy - sx * sy) / det
    log_k = (sy - n * sx) / sw
    return float(np.sum((f - np.exp(log_k + n * x)) ** 2))


@dataclass(frozen=True)
class ContactPoint:
    """A seating offset found in a record: re-zero z at ``z_contact`` [m]."""

    z_contact: float
    before: np.ndarray  # positions with 0 < z <= z_contact (free travel), excluded
    residual_ratio: float  # residual from the contact / residual from z = 0


def find_contact(z: np.ndarray, force: np.ndarray) -> ContactPoint | None:
    """A pre-contact segment (force at its noise floor while z > 0 grows), or None.

    The candidate is the free travel before the force first rises (and stays, three samples)
    :data:`CONTACT_NOISE_WIDTHS` noise widths above its starting level. It is a seating
    offset only if it is material (:data:`CONTACT_MIN_TRAVEL` of the travel) and a power law
    measured from a contact point inside it fits the loaded record with at most
    :data:`CONTACT_RESIDUAL_RATIO` of the residual of one measured from z = 0 — a steep
    power law (n > 1) also starts near the noise floor, but shifting its origin fits worse.
    """
    z, force = np.asarray(z, float), np.asarray(force, float)
    if z.size < 8:
        return None
    base = float(np.median(force[:3]))
    noise = max(_robust_width(np.diff(force, 2)) / np.sqrt(6.0), _quantum(force))
    if abs(base) > max(CONTACT_MAX_START * abs(float(force.max())), CONTACT_NOISE_WIDTHS * noise):
        return None  # the record starts under load: its flat start is not a noise floor
    threshold = base + max(CONTACT_NOISE_WIDTHS * noise, 0.01 * float(force.max() - base))
    above = force > threshold
    rising = above[:-2] & above[1:-1] & above[2:]
    if not rising.any():
        return None
    first = int(np.argmax(rising))
    travel = float(z.max() - max(z.min(), 0.0))
    free = np.flatnonzero((np.arange(z.size) < first) & (z > 0))
    if free.size < 3 or travel <= 0:
        return None
    z_free = float(z[free].max())
    if z_free < CONTACT_MIN_TRAVEL * travel:
        return None
    loaded = np.arange(z.size) >= first
    zl, fl = z[loaded], force[loaded] - base
    from_zero = _power_law_residual(zl, fl, 0.0)
    upper = float(zl[zl > 0].min()) if (zl > 0).any() else 0.0
    if upper <= 0:
        return None
    # A coarse grid first: most candidates are steep power laws that no offset improves.
    grid = upper * np.linspace(0.0, 1.0, 12, endpoint=False)[1:]
    coarse = np.array([_power_law_residual(zl, fl, ref) for ref in grid])
    if not from_zero > 0 or coarse.min() > 0.8 * from_zero:
        return None
    best = minimize_scalar(
        lambda ref: _power_law_residual(zl, fl, ref),
        bounds=(0.0, upper * (1 - 1e-9)),
        method="bounded",
        options={"xatol": 1e-6 * travel},
    )
    refined = (float(best.fun), float(best.x))
    fun, z_contact = min(refined, (float(coarse.min()), float(grid[coarse.argmin()])))
    ratio = fun / from_zero
    if not ratio <= CONTACT_RESIDUAL_RATIO or z_contact < CONTACT_MIN_TRAVEL * travel:
        return None
    before = np.flatnonzero((z > 0) & (z <= z_contact))
    return ContactPoint(z_contact, before, ratio)


@dataclass(frozen=True)
class Runaway:
    """Sinkage far beyond the record's own early power law (bearing failure)."""

    z_onset: float  # last sinkage [m] the early law still describes (the proposed z_max)
    after: np.ndarray  # positions past the onset
    excess: float  # final sinkage / the early law's sinkage at the final force


def find_runaway(z: np.ndarray, force: np.ndarray) -> Runaway | None:
    """Bearing failure: at the end of the record the plate sits :data:`RUNAWAY_EXCESS` times
    deeper than the record's own early power law puts it at the same force.

    The early law is F = k z^n, fitted in log–log space to the samples up to the sinkage
    where the force first reaches 35 % of its peak (and above 5 % of it). Comparing sinkage
    at equal force makes the rule hold for load- and displacement-controlled tests alike: a
    force plateau and a sinkage jump at one load step both show as excess sinkage. The
    onset is the last sample within :data:`RUNAWAY_ONSET` of that law; the excess travel must
    also exceed :data:`RUNAWAY_MIN_TRAVEL` of the final sinkage.
    """
    z, force = np.asarray(z, float), np.asarray(force, float)
    if z.size < 8:
        return None
    f = median_filter(force, size=5, mode="nearest")
    start = float(np.median(force[:3]))
    if abs(start) < 0.02 * abs(float(f.max())):  # a sensor offset, not a test begun loaded
        f = f - start
    peak = float(f.max())
    if peak <= 0:
        return None
    reach = int(np.argmax(f >= 0.35 * peak))
    early = (z > 0) & (np.arange(z.size) <= reach) & (f > 0.05 * peak)
    if early.sum() < 4 or np.ptp(np.log(z[early])) <= 0:
        return None
    n, log_k = np.polyfit(np.log(z[early]), np.log(f[early]), 1)
    if not n > 0:
        return None
    loaded = f > 0
    ratio = np.full(z.size, np.nan)
    ratio[loaded] = z[loaded] / np.exp((np.log(f[loaded]) - log_k) / n)
    last = int(np.flatnonzero(np.isfinite(ratio))[-1])
    z_end = float(z[last])
    excess = float(ratio[last])
    if not excess > RUNAWAY_EXCESS or z_end * (1 - 1 / excess) <= RUNAWAY_MIN_TRAVEL * z_end:
        return None
    within = np.flatnonzero(np.nan_to_num(ratio, nan=0.0) <= RUNAWAY_ONSET)
    onset = int(within[-1]) if within.size else 0
    return Runaway(float(z[onset]), np.arange(onset + 1, z.size), excess)


def find_non_monotone(z: np.ndarray) -> np.ndarray:
    """Positions where z lies below its running maximum by more than
    :data:`FALLBACK_FRACTION` of the travel, in runs of :data:`FALLBACK_MIN_RUN` or more."""
    z = np.asarray(z, float)
    if z.size < FALLBACK_MIN_RUN + 1:
        return np.array([], int)
    travel = float(z.max() - z.min())
    if travel <= 0:
        return np.array([], int)
    fallen = (np.maximum.accumulate(z) - z) > FALLBACK_FRACTION * travel
    keep = [np.arange(a, b) for a, b in _runs(fallen) if b - a >= FALLBACK_MIN_RUN]
    return np.concatenate(keep) if keep else np.array([], int)


def find_saturation(values: np.ndarray, other: np.ndarray) -> np.ndarray:
    """Positions where ``values`` sit exactly at their maximum (≥ :data:`SATURATION_MIN_SAMPLES`
    samples) while ``other`` changes across them by more than 1 % of its span."""
    x, y = np.asarray(values, float), np.asarray(other, float)
    at_max = np.flatnonzero(x == x.max())
    if at_max.size < SATURATION_MIN_SAMPLES:
        return np.array([], int)
    span = float(y.max() - y.min())
    if span <= 0 or float(np.ptp(y[at_max])) <= 0.01 * span:
        return np.array([], int)
    return at_max
