"""Isolated spikes in one record (``spike``): samples far off the running median of five,
in noise widths of their own record and their neighbourhood, and not a feature of the
record (numpy arrays in record order)."""

from __future__ import annotations

import numpy as np
from scipy.ndimage import median_filter

from .noise import quantum, runs

#: Spikes: departure from the running median (width 5) in robust noise widths ...
SPIKE_NOISE_WIDTHS = 10.0
#: ... and as a fraction of the test's span (smaller glitches do not move a fit).
SPIKE_SPAN_FRACTION = 0.05
#: A run longer than this is a feature of the record, not a spike.
SPIKE_MAX_RUN = 2
#: Off samples within 2 of each other are one spike and the neighbours whose running median
#: it drags along when that sample departs this many times more than any other of them and,
#: set to its running median, leaves none of them off (sparse, steep records).
SPIKE_LONE_DOMINANCE = 3.0


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
    width = max(1.4826 * float(np.median(second)), quantum(x), 1e-9 * span)
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
    off = drop_dragged(x, off, width, span)
    keep = [np.arange(a, b) for a, b in runs(off) if b - a <= SPIKE_MAX_RUN]
    return np.concatenate(keep) if keep else np.array([], int)


def _clusters(off: np.ndarray) -> list[np.ndarray]:
    """Off samples grouped where each lies within the running median's reach (2) of the
    next: the samples one spike can drag off with it."""
    at = np.flatnonzero(off)
    if at.size < 2:
        return []
    return [c for c in np.split(at, np.flatnonzero(np.diff(at) > 2) + 1) if c.size > 1]


def drop_dragged(x: np.ndarray, off: np.ndarray, width: float, span: float) -> np.ndarray:
    """``off`` without the samples that are off only because one spike near them drags
    their running median along.

    On a sparse, steep record one spike shifts the running median of five of its
    neighbours by a rank, a whole step of the ramp, so they depart too (GRC-1: a force spike
    x4 departs by 682 noise widths, its two followers by 68 and 65: a run of three, which
    no spike may be, and the spike went unflagged; a sinkage spike x3 excluded a good
    sample near it).  In each group of off samples within 2 of each other, the one that
    departs most is the lone spike when it departs :data:`SPIKE_LONE_DOMINANCE` times more
    than any other of the group and, set to its running median, leaves none of them off;
    the others are then not off.  A pair of spikes drags a good neighbour almost as far as
    itself, so no one sample of it stands out.
    """
    groups = _clusters(off)
    if not groups:
        return off
    off = off.copy()
    smooth = median_filter(x, size=5, mode="nearest")
    departure = np.abs(x - smooth)
    for group in groups:
        i = int(group[np.argmax(departure[group])])
        others = group[group != i]
        if departure[others].max() * SPIKE_LONE_DOMINANCE > departure[i]:
            continue  # no one sample stands out: a pair, or a feature of the record
        alone = x.copy()
        alone[i] = smooth[i]
        rest = np.abs(alone - median_filter(alone, size=5, mode="nearest"))[others]
        if not ((rest > SPIKE_NOISE_WIDTHS * width) & (rest > SPIKE_SPAN_FRACTION * span)).any():
            off[others] = False
    return off
