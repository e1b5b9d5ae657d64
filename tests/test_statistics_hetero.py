"""One variance per factor level with a random block (soilstats.statistics.hetero).

Truth is planted: tables with known per-level variances (Shukla's estimator must average to
them), and per-test campaigns shaped like the bundled preparation design (13 methods,
3 operators, 3 plates, 2 tests per cell) with no method effect, per-method scatter from
0.035 to 0.14 log10 and operator biases on two methods only — the pooled F's level fails
there, the Welch-type test's must hold — or with a planted method effect.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from soilstats.statistics import (
    StatisticsInputError,
    anova_random_block,
    shukla_variances,
    welch_random_block,
)

# log10 per-test scatter and method × operator bias sd per method, as the bundled simulator
# (stiffness cv 0.08–0.32 → /ln 10; operator_cv 0.15 / 0.20 for methods 9 / 10)
SCATTER = np.array([0.14, 0.15, 0.16, 0.16, 0.14, 0.15, 0.16, 0.17, 0.28, 0.32, 0.11, 0.13, 0.08])
SCATTER = SCATTER / np.log(10)
INTER = np.zeros(13)
INTER[8], INTER[9] = 0.15 / np.log(10), 0.20 / np.log(10)


def campaign(rng, *, shift=0.0, shifted=12, operator_sd=0.05):
    """Per-test log10 p_ref: plate +0.1 log10 per size, operator main effects N(0, sd²),
    method × operator biases N(0, INTER²), scatter N(0, SCATTER²); method ``shifted`` + shift."""
    op = operator_sd * rng.standard_normal(3)
    inter = INTER[:, None] * rng.standard_normal((13, 3))
    m, o, p, _ = np.meshgrid(np.arange(13), np.arange(3), np.arange(3), np.arange(2), indexing="ij")
    m, o, p = m.ravel(), o.ravel(), p.ravel()
    y = 0.1 * p + op[o] + inter[m, o] + SCATTER[m] * rng.standard_normal(m.size)
    y = y + shift * (m == shifted)
    return pd.DataFrame(
        dict(
            method=(m + 1).astype(str), operator=np.array(list("ABC"))[o], b_m=0.025 * (p + 1), y=y
        )
    )


def test_shukla_variances_average_to_the_planted_ones():
    rng = np.random.default_rng(1)
    v = np.array([0.2, 1.0, 0.05, 3.0, 0.5])
    cols = 4
    e = rng.standard_normal((40_000, 5, cols)) * np.sqrt(v)[:, None]
    y = e + rng.normal(0, 2.0, (40_000, 1, cols)) + np.arange(5)[:, None]  # columns cancel
    est = shukla_variances(y).mean(0)
    # the standard error of each mean is < 1 % of the largest v here
    np.testing.assert_allclose(est, v, atol=0.04)
    with pytest.raises(StatisticsInputError, match="three or more levels"):
        shukla_variances(y[0, :2])


@pytest.mark.slow
def test_prep_level_holds_where_the_pooled_f_does_not():
    rng = np.random.default_rng(2026)
    runs = 300
    welch, pooled = 0, 0
    for _ in range(runs):
        d = campaign(rng)
        welch += (
            welch_random_block(
                d, "y", "method", ["b_m", "operator"], "operator", n_boot=199
            ).p_value
            < 0.05
        )
        t = anova_random_block(d, "y", "method", ["b_m", "operator"], "operator")
        pooled += t.loc["method", "PR(>F)"] < 0.05
    # Binomial(300, 0.05): P(≥ 25) ≈ 0.01; the pooled F rejects ≈ 17 % of these campaigns
    assert welch <= 24, welch
    assert pooled >= 36, pooled


def test_planted_effect_on_the_precise_method_is_found():
    # method 13 (scatter 0.035 log10) × 1.58 pressure, against shovel methods' 0.14 scatter
    for seed in range(3):
        d = campaign(np.random.default_rng(50 + seed), shift=0.2)
        r = welch_random_block(d, "y", "method", ["b_m", "operator"], "operator")
        assert r.p_value < 0.01, r


def test_operator_main_effects_and_a_constant_change_nothing():
    d = campaign(np.random.default_rng(7))
    moved = d.assign(y=d["y"] + 5.0 + d["operator"].map({"A": 0.3, "B": -1.0, "C": 2.0}))
    a = welch_random_block(d, "y", "method", ["b_m", "operator"], "operator")
    b = welch_random_block(moved, "y", "method", ["b_m", "operator"], "operator")
    assert b.statistic == pytest.approx(a.statistic, rel=1e-9)
    assert b.p_value == a.p_value and 0 < a.p_value <= 1
    assert "one variance per method" in a.test and np.isnan(a.df_den)


def test_designs_without_one_variance_per_level_are_refused():
    d = campaign(np.random.default_rng(3))
    blocks = ["b_m", "operator"]
    two = d[d["method"].isin(["1", "2"])]
    with pytest.raises(StatisticsInputError, match="three or more levels"):
        welch_random_block(two, "y", "method", blocks, "operator")
    hole = d[~((d["method"] == "1") & (d["operator"] == "A"))]
    with pytest.raises(StatisticsInputError, match="every method × operator cell"):
        welch_random_block(hole, "y", "method", blocks, "operator")
    single = d.groupby(["method", "operator"]).head(1)
    with pytest.raises(StatisticsInputError, match="no replicate"):
        welch_random_block(single, "y", "method", "operator", "operator")
    with pytest.raises(StatisticsInputError, match="one of the blocks"):
        welch_random_block(d, "y", "method", "b_m", "operator")
