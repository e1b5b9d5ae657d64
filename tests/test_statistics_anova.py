"""One-way and two-way ANOVA, and effect sizes: input errors and independent cross-checks.

Truth here is (a) statsmodels' OLS table on well-conditioned data, (b) residual sums of squares
of nested least-squares models computed directly with numpy, (c) closed forms.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import statsmodels.formula.api as smf
from scipy import stats
from statsmodels.stats.anova import anova_lm

from soilstats.statistics import (
    ConfoundingError,
    StatisticsInputError,
    anova_oneway,
    anova_twoway,
    effect_sizes,
)
from soilstats.statistics.twoway import dummy_design


def _oneway_data(rng, means=(1.0, 1.5, 2.0), n=(5, 7, 6), sd=0.3):
    rows = [
        {"method": f"m{j}", "n": mu + sd * rng.standard_normal()}
        for j, (mu, nj) in enumerate(zip(means, n, strict=True))
        for _ in range(nj)
    ]
    return pd.DataFrame(rows)


def _rss(x, y):
    beta, *_ = np.linalg.lstsq(x, y, rcond=None)
    r = y - x @ beta
    return float(r @ r)


# -- one-way ----------------------------------------------------------------------------------
def test_oneway_matches_statsmodels_and_closed_form():
    d = _oneway_data(np.random.default_rng(1))
    t = anova_oneway(d, "n", "method")
    ref = anova_lm(smf.ols("n ~ C(method)", d).fit())
    assert list(t.columns) == ["df", "sum_sq", "mean_sq", "F", "PR(>F)"]
    assert list(t.index) == ["between", "within"]
    np.testing.assert_allclose(t["sum_sq"], ref["sum_sq"], rtol=1e-12)
    np.testing.assert_allclose(t.loc["between", "F"], ref["F"].iloc[0], rtol=1e-12)
    np.testing.assert_allclose(t.loc["between", "PR(>F)"], ref["PR(>F)"].iloc[0], rtol=1e-10)
    assert math.isnan(t.loc["within", "F"]) and math.isnan(t.loc["within", "PR(>F)"])
    assert t.attrs["n_obs"] == 18 and t.attrs["n_levels"] == 3 and t.attrs["n_dropped"] == 0
    f = stats.f_oneway(*[g["n"].to_numpy() for _, g in d.groupby("method")])
    np.testing.assert_allclose(t.loc["between", "F"], f.statistic, rtol=1e-12)


def test_oneway_does_not_mutate_and_is_shift_invariant():
    d = _oneway_data(np.random.default_rng(2))
    before = d.copy()
    t = anova_oneway(d, "n", "method")
    pd.testing.assert_frame_equal(d, before)
    shifted = d.assign(n=d["n"] + 1e9)
    t2 = anova_oneway(shifted, "n", "method")
    np.testing.assert_allclose(t2["sum_sq"], t["sum_sq"], rtol=1e-6)


def test_oneway_without_scatter():
    d = pd.DataFrame({"g": list("aabb"), "y": [1.0, 1.0, 2.0, 2.0]})
    t = anova_oneway(d, "y", "g")
    assert t.loc["between", "F"] == math.inf and t.loc["between", "PR(>F)"] == 0.0
    t = anova_oneway(d.assign(y=1.0), "y", "g")
    assert math.isnan(t.loc["between", "F"])


@pytest.mark.parametrize(
    ("frame", "response", "factor", "match"),
    [
        (pd.DataFrame({"g": [1, 2], "y": [1.0, 2.0]}), "y", "method", "column 'method'.*not in"),
        (pd.DataFrame({"g": [1, 1, 1], "y": [1.0, 2, 3]}), "y", "g", "at least 2 distinct"),
        (pd.DataFrame({"g": [1, 1, 2, 2], "y": [1.0, 2, np.inf, 3]}), "y", "g", "non-finite"),
        (pd.DataFrame({"g": [1, 1, 2, 2], "y": ["a", "b", "c", "d"]}), "y", "g", "numbers"),
        (pd.DataFrame({"g": [1, 2, 3], "y": [1.0, 2, 3]}), "y", "g", "single observation"),
        (pd.DataFrame({"g": [1, 1, 2, 2], "y": [1.0, 2, np.nan, 3]}), "y", "g", "dropna=True"),
        (pd.DataFrame({"g": [1, 1, None, 2], "y": [1.0, 2, 2, 3]}), "y", "g", "1 row"),
        ([1, 2, 3], "y", "g", "DataFrame"),
    ],
)
def test_oneway_input_errors(frame, response, factor, match):
    with pytest.raises(StatisticsInputError, match=match) as info:
        anova_oneway(frame, response, factor)
    assert isinstance(info.value, ValueError)


def test_oneway_empty_categorical_level_is_named():
    d = pd.DataFrame(
        {"g": pd.Categorical(["a", "a", "b", "b"], categories=["a", "b", "c"]), "y": [1.0, 2, 3, 5]}
    )
    with pytest.raises(StatisticsInputError, match=r"\['c'\] have no observations") as info:
        anova_oneway(d, "y", "g")
    assert info.value.column == "g"


def test_oneway_dropna_reports_count():
    d = _oneway_data(np.random.default_rng(3))
    clean = anova_oneway(d, "n", "method")
    dirty = pd.concat([d, pd.DataFrame({"method": ["m0", None], "n": [np.nan, 1.0]})])
    t = anova_oneway(dirty, "n", "method", dropna=True)
    assert t.attrs["n_dropped"] == 2
    pd.testing.assert_frame_equal(t, clean, check_like=False)


# -- effect sizes -----------------------------------------------------------------------------
def test_effect_sizes_closed_form_oneway():
    d = _oneway_data(np.random.default_rng(4))
    t = anova_oneway(d, "n", "method")
    e = effect_sizes(t).loc["between"]
    ssb, ssw = t["sum_sq"]
    dfb, dfw = t["df"]
    msw = ssw / dfw
    assert e["eta_sq"] == pytest.approx(ssb / (ssb + ssw), rel=1e-12)
    assert e["partial_eta_sq"] == pytest.approx(e["eta_sq"], rel=1e-12)
    assert e["omega_sq"] == pytest.approx((ssb - dfb * msw) / (ssb + ssw + msw), rel=1e-12)
    assert e["partial_omega_sq"] == pytest.approx(e["omega_sq"], rel=1e-12)
    r2 = smf.ols("n ~ C(method)", d).fit().rsquared
    assert e["eta_sq"] == pytest.approx(r2, rel=1e-10)


def test_effect_sizes_refuses_foreign_table():
    with pytest.raises(StatisticsInputError, match="residual row"):
        effect_sizes(pd.DataFrame({"df": [1.0], "sum_sq": [2.0]}, index=["x"]))
    with pytest.raises(StatisticsInputError, match="sum_sq"):
        effect_sizes(pd.DataFrame({"df": [1.0]}))


# -- two-way (blocked) ------------------------------------------------------------------------
def _blocked_data(rng, effect=0.0, block_effect=1.0, n_per_cell=3, drop=5):
    rows = []
    for i, a in enumerate(["v1", "v2", "v3"]):
        for j, b in enumerate(["day1", "day2", "day3", "day4"]):
            for _ in range(n_per_cell):
                y = 10 + effect * i + block_effect * j + 0.5 * rng.standard_normal()
                rows.append({"velocity": a, "session": b, "k c": y})
    d = pd.DataFrame(rows)
    return d.drop(index=rng.choice(len(d), size=drop, replace=False)).reset_index(drop=True)


def test_twoway_type2_equals_nested_rss_differences():
    """Type II F of each term = (RSS without it − RSS with it)/df ÷ MS_residual (unbalanced)."""
    d = _blocked_data(np.random.default_rng(5), effect=0.4)
    t = anova_twoway(d, "k c", "velocity", "session")
    y = d["k c"].to_numpy()
    x_full = dummy_design(d, ["velocity", "session"])
    rss_full = _rss(x_full, y)
    df_res = len(y) - x_full.shape[1]
    assert t.loc["Residual", "df"] == df_res
    assert t.loc["Residual", "sum_sq"] == pytest.approx(rss_full, rel=1e-10)
    for term, other in [("velocity", "session"), ("session", "velocity")]:
        x_red = dummy_design(d, [other])
        df = x_full.shape[1] - x_red.shape[1]
        ss = _rss(x_red, y) - rss_full
        assert t.loc[term, "sum_sq"] == pytest.approx(ss, rel=1e-9)
        f = (ss / df) / (rss_full / df_res)
        assert t.loc[term, "F"] == pytest.approx(f, rel=1e-9)
        assert t.loc[term, "PR(>F)"] == pytest.approx(stats.f.sf(f, df, df_res), rel=1e-8)
    assert t.attrs["typ"] == 2 and not t.attrs["balanced"]
    yc = y - y.mean()
    assert t.attrs["ss_total"] == pytest.approx(yc @ yc, rel=1e-12)
    pe = effect_sizes(t).loc["velocity", "partial_eta_sq"]
    ss_v, ss_e = t.loc["velocity", "sum_sq"], t.loc["Residual", "sum_sq"]
    assert pe == pytest.approx(ss_v / (ss_v + ss_e), rel=1e-12)


def test_twoway_interaction_and_balanced():
    d = _blocked_data(np.random.default_rng(6), drop=0)
    t = anova_twoway(d, "k c", "velocity", "session", interaction=True)
    assert list(t.index) == ["velocity", "session", "velocity:session", "Residual"]
    assert t.attrs["balanced"]
    ref = anova_lm(smf.ols("Q('k c') ~ C(velocity) * C(session)", d).fit(), typ=1)
    np.testing.assert_allclose(t["sum_sq"].to_numpy(), ref["sum_sq"].to_numpy(), rtol=1e-9)


def test_twoway_confounding_is_refused():
    d = pd.DataFrame(
        {
            "method": ["m1"] * 4 + ["m2"] * 4 + ["m3"] * 4,
            "session": ["d1"] * 4 + ["d2"] * 4 + ["d2"] * 2 + ["d3"] * 2,
            "y": np.arange(12.0) % 5,
        }
    )
    with pytest.raises(ConfoundingError, match="confounded") as info:
        anova_twoway(d, "y", "method", "session")
    assert info.value.df_lost == 1 and info.value.factor == "method"
    assert isinstance(info.value, ValueError)


def test_twoway_input_errors():
    d = _blocked_data(np.random.default_rng(7), drop=0)
    with pytest.raises(StatisticsInputError, match="operator"):
        anova_twoway(d, "k c", "velocity", "operator")
    with pytest.raises(StatisticsInputError, match="exactly one block"):
        anova_twoway(d.assign(op=1), "k c", "velocity", ["session", "op"], interaction=True)
    sparse = d[~((d.velocity == "v1") & (d.session == "day1"))]
    with pytest.raises(StatisticsInputError, match="every cell"):
        anova_twoway(sparse, "k c", "velocity", "session", interaction=True)
    one_per_cell = d.groupby(["velocity", "session"]).head(1)
    with pytest.raises(StatisticsInputError, match="no residual"):
        anova_twoway(one_per_cell, "k c", "velocity", "session", interaction=True)


def test_twoway_detects_planted_effect_despite_blocks():
    d = _blocked_data(np.random.default_rng(8), effect=1.0, block_effect=3.0)
    t = anova_twoway(d, "k c", "velocity", "session")
    assert t.loc["velocity", "PR(>F)"] < 1e-6
    # the one-way test drowns the same effect in the block-to-block variation
    assert anova_oneway(d, "k c", "velocity").loc["between", "PR(>F)"] > 1e-3
