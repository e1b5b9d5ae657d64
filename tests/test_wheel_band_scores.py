"""One scorer of predicted bands against measured values (soilstats.wheel.band_scores),
serving the validation's plate-only bands and the calibration's held-out bands (issue #45:
the two had their own copies)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from soilstats.wheel.band_scores import BandColumns, score_bands
from soilstats.wheel.calibration.heldout import score
from soilstats.wheel.validation_scoring import _summ

# Four runs worked by hand: errors (median − measured) 0.5, -1, 0 and — for the unmeasured
# run — nothing; the band [lower, upper] covers runs 1 (inside) and 3 (on its lower end),
# not run 2 (below it).
MEASURED = [1.0, 3.0, 2.0, np.nan]
MEDIAN = [1.5, 2.0, 2.0, 4.0]
LOWER = [0.0, 3.5, 2.0, 3.0]
UPPER = [2.0, 4.0, 3.0, 5.0]


def test_scores_worked_by_hand():
    frame = pd.DataFrame({"y": MEASURED, "m": MEDIAN, "lo": LOWER, "hi": UPPER})
    s = score_bands(frame, BandColumns("y", "m", "lo", "hi"))
    assert s.runs == 3 and s.covered == 2 and s.coverage == 2 / 3
    assert s.median_width == 1.0  # widths 2, 0.5, 1
    assert s.bias == (0.5 - 1 + 0) / 3 and s.median_bias == 0.0 and s.mae == 0.5
    assert s.measured_mean == 2.0 and s.predicted_mean == 5.5 / 3
    bare = score_bands(frame, BandColumns("y", "m"))
    assert bare.covered is None and bare.coverage is None and bare.mae == 0.5


def test_no_run_scored_gives_nan_not_an_error():
    frame = pd.DataFrame({"y": [np.nan], "m": [1.0], "lo": [0.0], "hi": [2.0]})
    s = score_bands(frame, BandColumns("y", "m", "lo", "hi"))
    assert s.runs == 0 and s.covered == 0 and s.coverage is not None and math.isnan(s.coverage)
    assert all(math.isnan(v) for v in (s.bias, s.mae, s.median_bias, s.measured_mean))


def test_both_scorings_are_the_one_scorer_under_their_own_column_names():
    held = pd.DataFrame(
        {
            "sinkage_m_measured": MEASURED,
            "sinkage_m_median": MEDIAN,
            "sinkage_m_lower": LOWER,
            "sinkage_m_upper": UPPER,
        }
    )
    assert score(held, "sinkage_m") == {
        "runs": 3,
        "covered": 2,
        "coverage_90": 2 / 3,
        "median_width_m": 1.0,
        "mae_m": 0.5,
        "bias_m": -0.5 / 3,
    }
    plate = pd.DataFrame(
        {
            "sinkage_measured_m": MEASURED,
            "sinkage_median_m": MEDIAN,
            "sinkage_lower_m": LOWER,
            "sinkage_upper_m": UPPER,
        }
    )
    assert _summ(plate) == {
        "runs": 3,
        "covered": 2,
        "coverage_90": 2 / 3,
        "bias_m": -0.5 / 3,
        "median_bias_m": 0.0,
        "mae_m": 0.5,
        "measured_mean_m": 2.0,
        "predicted_mean_m": 5.5 / 3,
    }
