"""ANOVA with a random block (operators): sums of squares against statsmodels, the F-test
against the factor × operator mean square, its level under a planted interaction."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import statsmodels.formula.api as smf
from scipy import stats
from statsmodels.stats.anova import anova_lm

from soilstats.statistics import (
    ConfoundingError,
    StatisticsInputError,
    anova_random_block,
    anova_twoway,
)


def _design(rng, *, methods=4, operators=3, plates=3, reps=2, sd_inter=0.0, shift=0.0):
    """log10 p_ref of a methods × operators × plates design; a persistent bias per method and
    operator N(0, sd_inter²), operator and plate main effects, scatter sd 0.04; method m0
    shifted by ``shift``."""
    op_bias = dict(zip(range(operators), 0.05 * rng.standard_normal(operators), strict=True))
    inter = sd_inter * rng.standard_normal((methods, operators))
    rows = []
    for m in range(methods):
        for o in range(operators):
            for p in range(plates):
                for _ in range(reps):
                    y = (shift if m == 0 else 0.0) + op_bias[o] + inter[m, o] + 0.1 * p
                    rows.append((f"m{m}", f"op{o}", 0.025 * (p + 1), y))
    d = pd.DataFrame(rows, columns=["method", "operator", "b_m", "y"])
    d["y"] += 0.04 * rng.standard_normal(len(d))
    return d


@pytest.mark.parametrize("drop", [[], [0, 5, 17, 40]])
def test_sums_of_squares_are_statsmodels_type2_and_f_uses_the_interaction(drop):
    d = _design(np.random.default_rng(3), sd_inter=0.05).drop(index=drop)
    t = anova_random_block(d, "y", "method", ["b_m", "operator"], "operator")
    ref = anova_lm(smf.ols("y ~ C(method) * C(operator) + C(b_m)", d).fit(), typ=2)
    names = {
        "method": "C(method)",
        "operator": "C(operator)",
        "b_m": "C(b_m)",
        "method:operator": "C(method):C(operator)",
        "Residual": "Residual",
    }
    for row, ref_row in names.items():
        assert t.loc[row, "sum_sq"] == pytest.approx(ref.loc[ref_row, "sum_sq"], rel=1e-9)
        assert t.loc[row, "df"] == ref.loc[ref_row, "df"]
    ms = t["sum_sq"] / t["df"]
    f = ms["method"] / ms["method:operator"]
    assert t.loc["method", "F"] == pytest.approx(f, rel=1e-12)
    p = stats.f.sf(f, t.loc["method", "df"], t.loc["method:operator", "df"])
    assert t.loc["method", "PR(>F)"] == pytest.approx(p, rel=1e-12)
    assert t.loc["method", "error_term"] == "method:operator"
    assert t.loc["b_m", "F"] == pytest.approx(ms["b_m"] / ms["Residual"], rel=1e-12)
    assert t.attrs["df_error"] == 6 and t.attrs["balanced"] is (not drop)


def test_refusals_name_the_reason():
    d = _design(np.random.default_rng(1))
    with pytest.raises(StatisticsInputError, match="must be one of the blocks"):
        anova_random_block(d, "y", "method", ["b_m"], "operator")
    one = d[d["b_m"] == 0.025].groupby(["method", "operator"], as_index=False).first()
    with pytest.raises(StatisticsInputError, match="no replicate") as err:
        anova_random_block(one, "y", "method", ["operator"], "operator")
    assert err.value.column == "y"
    # each operator tests its own methods but A tests m0 and m1, B only m1: no interaction df
    sparse = d[d["method"].isin(["m0", "m1"]) & d["operator"].isin(["op0", "op1"])]
    sparse = sparse[~((sparse["method"] == "m0") & (sparse["operator"] == "op1"))]
    with pytest.raises(StatisticsInputError, match="interaction can be estimated") as err:
        anova_random_block(sparse, "y", "method", ["b_m", "operator"], "operator")
    assert err.value.column == "operator"
    nested = d[
        (d["method"] == "m0") & (d["operator"] == "op0")
        | (d["method"] == "m1") & (d["operator"] == "op1")
    ]
    with pytest.raises(ConfoundingError):
        anova_random_block(nested, "y", "method", ["operator"], "operator")


@pytest.mark.slow
def test_level_under_a_method_by_operator_interaction():
    """No method effect, persistent method × operator biases (sd 0.06 log10, larger than the
    scatter): against the residual the test rejects far more than α; against the
    interaction at α."""
    rng = np.random.default_rng(2027)
    runs, mixed, fixed = 200, 0, 0
    for _ in range(runs):
        d = _design(rng, sd_inter=0.06)
        mixed += (
            anova_random_block(d, "y", "method", ["b_m", "operator"], "operator").loc[
                "method", "PR(>F)"
            ]
            < 0.05
        )
        fixed += anova_twoway(d, "y", "method", ["b_m", "operator"]).loc["method", "PR(>F)"] < 0.05
    # Binomial(200, 0.05): P(≥ 22) < 10⁻³
    assert mixed <= 21, mixed
    assert fixed > 50, fixed  # the test against the residual, for contrast


def test_the_effect_size_is_taken_against_the_term_the_f_test_uses():
    # The verdict's partial eta^2 came from the residual while F and p came from the
    # method x operator mean square (F = 0.76, p = 0.56 reported with eta^2 = 0.18).
    from soilstats.statistics.verdict import effect_row

    d = _design(np.random.default_rng(5), sd_inter=0.08)
    t = anova_random_block(d, "y", "method", ["b_m", "operator"], "operator")
    row = effect_row("s", "y", "method", t)
    ss = t.loc["method", "sum_sq"]
    assert row["effect_size"] == pytest.approx(ss / (ss + t.loc["method:operator", "sum_sq"]))
    assert row["statistic"] == t.loc["method", "F"]


def test_exact_data_give_no_test_rather_than_an_infinite_one():
    # Noise-free responses: F = inf and p = 0 with RuntimeWarnings, every pair "different".
    from soilstats.statistics import StatisticsInputError, tukey_lsmeans

    d = _design(np.random.default_rng(1), shift=0.2)
    d["y"] = np.where(d["method"] == "m0", 0.2, 0.0) + 0.1 * d["b_m"] / 0.025
    t = anova_random_block(d, "y", "method", ["b_m", "operator"], "operator")
    assert np.isnan(t.loc["method", "F"]) and np.isnan(t.loc["method", "PR(>F)"])
    with pytest.raises(StatisticsInputError, match="exact data"):
        tukey_lsmeans(d, "y", "method", ["b_m"], error=(0.0, 6))
