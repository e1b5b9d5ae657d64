"""Glitch clusters: dense runs of 5 or more samples that are physically impossible for the
record — a channel far beyond the record's own range — and come back (the
``glitch-cluster`` code).

A portable rig's displacement channel can jump for tens of samples to several times the
record's depth (60–350 mm in a 30 mm record) and return. The spike and burst rules judge a
sample against a running median of 5 or 11, which a run of 50 off samples owns, so such a
cluster stayed in the fits (a soil's pooled n 0.52 ± 0.23 with the clusters, 1.38 ± 0.06
without) and the good samples behind it were called non-monotone. This rule runs first, on
the raw records, per channel (z and force):

1. the record's robust range: its :data:`LOW_QUANTILE` and :data:`HIGH_QUANTILE` quantiles
   (a quarter of the samples may be off without moving the high one past the true top);
   ``depth`` is their difference;
2. candidates lie more than :data:`GLITCH_DEPTHS` depths beyond that range (above the high
   quantile or below the low one); candidates at most :data:`CLUSTER_GAP` samples apart
   form one cluster;
3. a cluster is a glitch when it holds at least :data:`GLITCH_MIN_SAMPLES` candidates and at
   most :data:`GLITCH_MAX_SHARE` of the record, has :data:`ANCHOR_SAMPLES` samples on each
   side, and every candidate departs from all of those anchors by more than
   :data:`GLITCH_DEPTHS` depths and :data:`GLITCH_NOISE_WIDTHS` noise widths: the record
   went there and came back, which a loading record (monotone in z, its force rising) never
   does. A run-away at the record's end has no anchors after it and is never a glitch.

Shorter events are the spike and burst rules' (:mod:`.records`, :mod:`.bursts`).
"""

from __future__ import annotations

import numpy as np

from .blocks import Blocks
from .noise import robust_width
from .report import QualityFlag
from .staging import leave_out

__all__ = [
    "GLITCH_DEPTHS",
    "GLITCH_MAX_SHARE",
    "GLITCH_MIN_SAMPLES",
    "find_glitch_clusters",
    "glitch_candidates",
]

#: The quantiles that give a record's robust range (a quarter of off samples on one side
#: leaves the high quantile at or below the true top).
LOW_QUANTILE = 0.05
HIGH_QUANTILE = 0.70
#: Candidates lie beyond the robust range by more than this many robust depths, and depart
#: from the anchors on both sides by as much.
GLITCH_DEPTHS = 1.0
#: ... and by more than this many noise widths of the record.
GLITCH_NOISE_WIDTHS = 10.0
#: Fewest candidates a glitch cluster holds (shorter runs are spikes and bursts) ...
GLITCH_MIN_SAMPLES = 5
#: ... and the largest share of the record it may cover.
GLITCH_MAX_SHARE = 0.25
#: Candidates at most this many samples apart belong to one cluster.
CLUSTER_GAP = 3
#: Good samples on each side of a cluster (the record before and after it).
ANCHOR_SAMPLES = 3
#: Fewest samples a record needs for the rule.
GLITCH_MIN_RECORD = 2 * ANCHOR_SAMPLES + GLITCH_MIN_SAMPLES + 9


def _quantiles(blocks: Blocks, values: np.ndarray, q: float) -> np.ndarray:
    """The ``q`` quantile (lower) of every block, across all blocks at once."""
    order = np.lexsort((values, blocks.block_of))
    ranked = values[order]
    at = blocks.starts + np.floor(q * np.maximum(blocks.sizes - 1, 0)).astype(np.int64)
    at = np.minimum(at, max(values.size - 1, 0))
    return np.where(blocks.sizes > 0, ranked[at] if values.size else 0.0, np.nan)


def glitch_candidates(blocks: Blocks, values: np.ndarray) -> np.ndarray:
    """Blocks with at least :data:`GLITCH_MIN_SAMPLES` samples beyond their robust range by
    :data:`GLITCH_DEPTHS` depths (the cheap pre-test, across all records at once)."""
    if not values.size:
        return np.array([], int)
    with np.errstate(invalid="ignore"):
        low = _quantiles(blocks, values, LOW_QUANTILE)
        high = _quantiles(blocks, values, HIGH_QUANTILE)
        depth = high - low
        beyond = (values > blocks.spread(high + GLITCH_DEPTHS * depth)) | (
            values < blocks.spread(low - GLITCH_DEPTHS * depth)
        )
    count = blocks.total_of(beyond)
    ok = (count >= GLITCH_MIN_SAMPLES) & (blocks.sizes >= GLITCH_MIN_RECORD) & (depth > 0)
    return np.flatnonzero(ok)


def find_glitch_clusters(values: np.ndarray) -> np.ndarray:
    """Positions of the samples of every glitch cluster in one record's channel (module
    docstring); empty when there is none."""
    x = np.asarray(values, float)
    n = x.size
    if n < GLITCH_MIN_RECORD or not np.isfinite(x).all():
        return np.array([], int)
    low, high = np.quantile(x, [LOW_QUANTILE, HIGH_QUANTILE], method="lower")
    depth = float(high - low)
    if depth <= 0:
        return np.array([], int)
    margin = GLITCH_DEPTHS * depth
    off = np.flatnonzero((x > high + margin) | (x < low - margin))
    if off.size < GLITCH_MIN_SAMPLES:
        return np.array([], int)
    good = np.ones(n, bool)
    good[off] = False
    noise = robust_width(np.diff(x[good], 2)) / np.sqrt(6.0) if good.sum() > 3 else 0.0
    need = max(margin, GLITCH_NOISE_WIDTHS * noise)
    found: list[np.ndarray] = []
    for cluster in np.split(off, np.flatnonzero(np.diff(off) > CLUSTER_GAP) + 1):
        a, b = int(cluster[0]), int(cluster[-1]) + 1
        if cluster.size < GLITCH_MIN_SAMPLES or b - a > GLITCH_MAX_SHARE * n:
            continue
        if a < ANCHOR_SAMPLES or b + ANCHOR_SAMPLES > n:
            continue  # no record on one side: an edge, not a glitch that came back
        anchors = np.r_[x[a - ANCHOR_SAMPLES : a], x[b : b + ANCHOR_SAMPLES]]
        up = x[cluster] > high
        departure = np.where(up, x[cluster] - anchors.max(), anchors.min() - x[cluster])
        if (departure > need).all():
            found.append(cluster)
    return np.concatenate(found) if found else np.array([], int)


def glitch_flags(
    ids: list[str], blocks: Blocks, columns: dict[str, np.ndarray], labels: np.ndarray, clean: bool
) -> tuple[list[list], list[np.ndarray], np.ndarray]:
    """``glitch-cluster`` flags of every record (either channel), the labels they drop in
    mode ``clean``, and the mask of glitched positions."""
    mask = np.zeros(blocks.total, dtype=bool)
    out: list[list] = [[] for _ in ids]
    drop: list[np.ndarray] = []
    judged = np.unique(np.concatenate([glitch_candidates(blocks, v) for v in columns.values()]))
    for k in judged.astype(int):
        at = slice(blocks.starts[k], blocks.starts[k] + blocks.sizes[k])
        hits = {name: find_glitch_clusters(values[at]) for name, values in columns.items()}
        found = np.unique(np.concatenate(list(hits.values()))).astype(int)
        if not found.size:
            continue
        mask[blocks.starts[k] + found] = True
        rows = labels[at][found]
        where = ", ".join(
            f"{h.size} in {name} (up to {np.abs(values[at][h]).max():.4g})"
            for (name, h), values in zip(hits.items(), columns.values(), strict=True)
            if h.size
        )
        message = (
            f"{found.size} samples in dense clusters far beyond the record's own range and "
            f"back ({where}); rule: glitch-cluster"
        )
        flag = QualityFlag(ids[k], "sinkage", "glitch-cluster", _rows(rows), message)
        leave_out(out[k], drop, flag, clean)
    return out, drop, mask


def _rows(labels: np.ndarray) -> tuple[int, ...]:
    return tuple(int(label) + 1 for label in labels.tolist())
