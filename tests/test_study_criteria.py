"""Criterion 2 of Table 1 (several persons, no remarkable differences) is decided per method.

Truth planted in a per-test table of 13 methods × 3 operators × 3 plates × 2 tests: one
method's operators differ (persistent biases −0.035 / 0 / +0.035 in log10 p_ref), the
others' do not.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from soilstats.study import load_spec
from soilstats.study.preparation import evaluate_criteria


def _soil(rng, biased="10", bias=0.035):
    rows = [
        dict(
            soil="s",
            preparation=str(m),
            operator=op,
            b_m=0.025 * (p + 1),
            log10_p_ref=0.1 * p + (bias * (o - 1) if str(m) == biased else 0.0),
        )
        for m in range(1, 14)
        for o, op in enumerate("ABC")
        for p in range(3)
        for _ in range(2)
    ]
    d = pd.DataFrame(rows)
    d["log10_p_ref"] += 0.04 * rng.standard_normal(len(d))
    return d


def test_an_operator_dependent_method_fails_criterion_2_at_alpha():
    d = _soil(np.random.default_rng(12))
    eps = pd.DataFrame({"soil": "s", "level": [str(m) for m in range(1, 14)], "epsilon": 0.9})
    table, _ = evaluate_criteria(d, eps, load_spec("preparation"), 0.05)
    row = table.set_index("method").loc["10"]
    # the planted bias is found at α (p ≈ 0.01) but not at Holm's α/13 for the soil
    assert row["operator_p"] < 0.05 <= row["operator_p_holm"]
    assert row["crit2"] == "-"
    assert "operator p = " in row["crit2_reason"]
