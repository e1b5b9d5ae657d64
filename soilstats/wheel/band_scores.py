"""How well predicted bands meet measured values: coverage, band width, mean absolute
error and bias, over any (measured, median, lower, upper) columns of a table.

One scorer for the wheel's two scorings (issue #45): the validation's plate-only bands
(:mod:`soilstats.wheel.validation_scoring`, columns ``sinkage_measured_m`` …) and the
calibration's held-out bands (:func:`soilstats.wheel.calibration.heldout.score`, columns
``sinkage_m_measured`` …); each picks the statistics it reports and their keys.

A run is scored where it was both measured and predicted (measured value and median
finite); a band covers it where lower ≤ measured ≤ upper (both ends included; a missing
end covers nothing).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

__all__ = ["BandColumns", "BandScores", "score_bands"]


@dataclass(frozen=True)
class BandColumns:
    """The columns of one quantity in a table of runs: the measured value, the predicted
    median and the band's lower and upper ends (None: the table has no band)."""

    measured: str
    median: str
    lower: str | None = None
    upper: str | None = None


@dataclass(frozen=True)
class BandScores:
    """The scores of one quantity over a set of runs, in the quantity's unit (m, N, N m).

    ``runs``: runs scored; ``covered``, ``coverage`` (share, NaN without runs),
    ``median_width`` (median of upper − lower): None without a band; ``bias`` and
    ``median_bias``: mean and median of predicted median − measured (> 0: predicted too
    high); ``mae``: mean absolute error; ``measured_mean``, ``predicted_mean``: the means
    of the two. NaN without runs.
    """

    runs: int
    covered: int | None
    coverage: float | None
    median_width: float | None
    bias: float
    median_bias: float
    mae: float
    measured_mean: float
    predicted_mean: float


def _mean(values: np.ndarray) -> float:
    return float(np.mean(values)) if len(values) else float("nan")


def score_bands(frame: pd.DataFrame, columns: BandColumns) -> BandScores:
    """Score the bands of ``columns`` against the measured values over the rows of
    ``frame`` (see the module docstring for which runs count and what covers)."""
    measured = frame[columns.measured].to_numpy(float)
    median = frame[columns.median].to_numpy(float)
    use = np.isfinite(measured) & np.isfinite(median)
    measured, median = measured[use], median[use]
    error = median - measured
    runs = int(use.sum())
    covered = coverage = width = None
    if columns.lower is not None and columns.upper is not None:
        lower = frame[columns.lower].to_numpy(float)[use]
        upper = frame[columns.upper].to_numpy(float)[use]
        covered = int(np.sum((lower <= measured) & (measured <= upper)))
        coverage = covered / runs if runs else float("nan")
        width = float(np.median(upper - lower)) if runs else float("nan")
    return BandScores(
        runs=runs,
        covered=covered,
        coverage=coverage,
        median_width=width,
        bias=_mean(error),
        median_bias=float(np.median(error)) if runs else float("nan"),
        mae=_mean(np.abs(error)),
        measured_mean=_mean(measured),
        predicted_mean=_mean(median),
    )
