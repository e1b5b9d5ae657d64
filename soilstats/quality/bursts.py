"""Bursts: runs of 1–5 samples that leave a record's local trend and come back, alone or in
clusters (the ``burst`` code).

The ``spike`` rule (:func:`~soilstats.quality.spikes.find_spikes`) judges a sample against
the running median of five, which a run of three or more off samples drags along: a 3–4
sample burst in z, or two spikes two samples apart, stay in the fits (a held-back soil's
pooled Bernstein n fell from 0.75–1.4 to 0.51). This rule runs after it, on the samples the
spike rule kept:

1. candidates depart from the running median of :data:`BURST_WINDOW` samples (a run of up
   to five is a minority there) by more than :data:`~.spikes.SPIKE_NOISE_WIDTHS` robust
   noise widths and :data:`~.spikes.SPIKE_SPAN_FRACTION` of the span (the spike rule's
   thresholds);
2. candidates within :data:`CLUSTER_GAP` samples of each other form one cluster;
3. a cluster is a burst when the good samples on both sides of it
   (:data:`ANCHOR_SAMPLES` each) lie on one straight line to within
   :data:`ANCHOR_TOLERANCE` of the cluster's smallest departure from that line, every
   departing sample lies on the same side of it, and no run of consecutive departing samples
   is longer than :data:`BURST_MAX_RUN`. A step, a release or the bend at a peak is no burst:
   the samples on its two sides are no single line.

A channel of a record is judged when it has :data:`BURST_MIN_SAMPLES` samples or more.
"""

from __future__ import annotations

import numpy as np

from .noise import resolution, robust_width, running_median
from .spikes import SPIKE_NOISE_WIDTHS, SPIKE_SPAN_FRACTION

__all__ = [
    "ANCHOR_SAMPLES",
    "ANCHOR_TOLERANCE",
    "BURST_MAX_RUN",
    "BURST_WINDOW",
    "CLUSTER_GAP",
    "find_bursts",
]

#: The longest run of consecutive off samples a burst may hold.
BURST_MAX_RUN = 5
#: Width of the running median the candidates depart from (a run of BURST_MAX_RUN is a
#: minority in it).
BURST_WINDOW = 2 * BURST_MAX_RUN + 1
#: Off samples at most this many samples apart belong to one cluster.
CLUSTER_GAP = 3
#: Good samples on each side of a cluster that must lie on one line with those of the other.
ANCHOR_SAMPLES = 3
#: ... to within this share of the cluster's smallest departure from that line.
ANCHOR_TOLERANCE = 0.2
#: Samples around a candidate whose second differences give its local noise (the spike
#: rule's 21).
LOCAL_WINDOW = 21
#: Fewest samples a record needs for the rule (two anchors of three and room for a burst).
BURST_MIN_SAMPLES = 12


def find_bursts(values: np.ndarray) -> np.ndarray:
    """Positions of the samples of every burst in ``values`` (module docstring)."""
    x = np.asarray(values, float)
    n = x.size
    if n < BURST_MIN_SAMPLES or not np.isfinite(x).all():
        return np.array([], int)
    trend = running_median(x, BURST_WINDOW)
    span = float(trend.max() - trend.min())
    if span <= 0:
        return np.array([], int)
    departure = np.abs(x - trend)
    if not (departure > SPIKE_SPAN_FRACTION * span).any():
        return np.array([], int)  # the threshold is at least this: nothing can be off
    width = max(robust_width(np.diff(x, 2)) / np.sqrt(6.0), resolution(x), 1e-9 * span)
    threshold = max(SPIKE_NOISE_WIDTHS * width, SPIKE_SPAN_FRACTION * span)
    off = np.flatnonzero(departure > threshold)
    if not off.size:
        return np.array([], int)
    # Judged against the local noise too (LOCAL_WINDOW samples around each): the noise of a
    # load cell grows with the load, and one sample of a noisy top is no burst.
    second = np.abs(np.diff(x, 2)) / np.sqrt(6.0)
    padded = np.pad(second, 1, mode="edge")
    half = LOCAL_WINDOW // 2
    local = np.array([1.4826 * np.median(padded[max(0, i - half) : i + half + 1]) for i in off])
    off = off[departure[off] > SPIKE_NOISE_WIDTHS * local]
    if not off.size:
        return np.array([], int)
    found: list[np.ndarray] = []
    for cluster in np.split(off, np.flatnonzero(np.diff(off) > CLUSTER_GAP) + 1):
        hit = _judge(x, int(cluster[0]), int(cluster[-1]) + 1, threshold)
        if hit is not None:
            found.append(hit)
    return np.concatenate(found) if found else np.array([], int)


def _judge(x: np.ndarray, a: int, b: int, threshold: float) -> np.ndarray | None:
    """The burst samples of the cluster spanning positions [a, b), or None."""
    if a < ANCHOR_SAMPLES or b + ANCHOR_SAMPLES > x.size:
        return None  # no anchors on one side: a burst cannot be told from an edge
    anchors = np.r_[np.arange(a - ANCHOR_SAMPLES, a), np.arange(b, b + ANCHOR_SAMPLES)]
    slope, intercept = np.polyfit(anchors, x[anchors], 1)
    inside = np.arange(a, b)
    departure = x[inside] - (slope * inside + intercept)
    far = np.abs(departure) > threshold
    if not far.any():
        return None
    edges = np.flatnonzero(np.diff(np.r_[0, far.astype(int), 0]))
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        side = np.sign(departure[start:stop])
        if (side != side[0]).any() or stop - start > BURST_MAX_RUN:
            return None  # a run crossing the line (a transition) or too long to be a burst
    anchor_misfit = np.abs(x[anchors] - (slope * anchors + intercept)).max()
    if anchor_misfit > ANCHOR_TOLERANCE * np.abs(departure[far]).min():
        return None  # the two sides are no single line: a step, a release, a peak
    return inside[far]
