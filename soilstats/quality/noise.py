"""The noise of one record, as every rule reads it: a robust noise width, the sensor's step
(quantisation), runs of a mask and a fast running median (numpy arrays in record order)."""

from __future__ import annotations

import numpy as np

#: Repeated readings in a run longer than this are a plateau (a hold: the drive stood still),
#: not the sensor's quantisation (:func:`resolution`).
PLATEAU_RUN = 3


def robust_width(values: np.ndarray) -> float:
    """1.4826 × median absolute deviation: the standard deviation of Gaussian noise."""
    if values.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(values - np.median(values))))


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) of each run of True in ``mask``."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def quantum(values: np.ndarray) -> float:
    """The sensor's step where the record is visibly quantised (≥ 10 % repeated readings),
    else 0: on a sparse record the smallest change is the signal's, not the sensor's.

    Repeats on a plateau at the record's maximum are a clipped channel (saturation), not
    the sensor's resolution, and are not counted (a clipped sparse record would otherwise
    take its smallest rise for the noise: 8.7 N instead of 0.35 N on a GRC-1 test).
    """
    steps = np.abs(np.diff(values))
    if steps.size == 0:
        return 0.0
    top = values == values.max()
    steps = steps[~(top[:-1] & top[1:])]
    if steps.size == 0 or np.mean(steps == 0) < 0.1:
        return 0.0
    steps = steps[steps > 0]
    return float(steps.min()) if steps.size else 0.0


def running_median(x: np.ndarray, size: int) -> np.ndarray:
    """``scipy.ndimage.median_filter(x, size, mode="nearest")`` for an odd ``size``: the
    middle of each window of the edge-padded record (one value of it, so exactly the
    filter's), without the filter's overhead on short records."""
    half = size // 2
    windows = np.lib.stride_tricks.sliding_window_view(np.pad(x, half, mode="edge"), size)
    return np.partition(windows, half, axis=1)[:, half]


def resolution(x: np.ndarray) -> float:
    """The sensor's step where the record is visibly quantised (10 % or more of its steps
    repeat a reading), else 0 — counting only repeats in runs of at most
    :data:`PLATEAU_RUN`: a hold repeats z for many samples without any quantisation, and
    its ramp's step is then no noise width."""
    steps = np.abs(np.diff(x))
    zero = steps == 0
    if not zero.any():
        return 0.0  # nothing repeats: no quantisation shows
    edges = np.flatnonzero(np.diff(np.r_[0, zero.astype(np.int8), 0]))
    starts, stops = edges[::2], edges[1::2]
    # Each step's run length (0 for a step that moves): a long run is a plateau, neither a
    # repeat nor a step.
    length = np.zeros(steps.size, dtype=np.int64)
    length[zero] = np.repeat(stops - starts, stops - starts)
    plateau = length > PLATEAU_RUN
    repeats = int((zero & ~plateau).sum())
    counted = steps.size - int(plateau.sum())
    if not counted or repeats < 0.1 * counted:
        return 0.0
    moving = steps[~zero]
    return float(moving.min()) if moving.size else 0.0
