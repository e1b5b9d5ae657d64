"""Tukey HSD, scatter tests and Welch's ANOVA against independent implementations."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from soilstats.statistics import (
    StatisticsInputError,
    anova_oneway,
    scatter_table,
    tukey_hsd,
    variance_test,
    welch_anova,
)


def _data(rng, means=(1.0, 1.6, 1.1, 2.0), sds=(0.3, 0.3, 0.3, 0.3), n=(6, 8, 5, 7)):
    rows = [
        {"shape": f"s{j}", "kc": mu + sd * rng.standard_normal()}
        for j, (mu, sd, nj) in enumerate(zip(means, sds, n, strict=True))
        for _ in range(nj)
    ]
    return pd.DataFrame(rows)


def _groups(d):
    return [g["kc"].to_numpy() for _, g in d.groupby("shape", sort=True)]


def test_tukey_matches_scipy():
    d = _data(np.random.default_rng(21))
    t = tukey_hsd(d, "kc", "shape", alpha=0.05)
    ref = stats.tukey_hsd(*_groups(d))
    ci = ref.confidence_interval(confidence_level=0.95)
    assert list(t.columns) == ["group1", "group2", "meandiff", "p_adj", "lower", "upper", "reject"]
    assert len(t) == 6
    levels = sorted(d["shape"].unique())
    for _, row in t.iterrows():
        i, j = levels.index(row["group1"]), levels.index(row["group2"])
        # scipy's statistic[i, j] is mean_i - mean_j; ours is mean(group2) - mean(group1)
        assert row["meandiff"] == pytest.approx(-ref.statistic[i, j], rel=1e-10)
        assert row["p_adj"] == pytest.approx(ref.pvalue[i, j], abs=2e-3)
        assert row["lower"] == pytest.approx(-ci.high[i, j], rel=1e-3)
        assert row["upper"] == pytest.approx(-ci.low[i, j], rel=1e-3)
        assert row["reject"] == (row["p_adj"] < 0.05)
    assert t.attrs["alpha"] == 0.05


def test_tukey_errors():
    d = _data(np.random.default_rng(22))
    with pytest.raises(StatisticsInputError, match="alpha"):
        tukey_hsd(d, "kc", "shape", alpha=5)
    mixed = pd.DataFrame({"g": [1, 1, "1", "1"], "y": [1.0, 2.0, 3.0, 4.0]})
    with pytest.raises(StatisticsInputError, match="same as strings"):
        tukey_hsd(mixed, "y", "g")


@pytest.mark.parametrize(("center", "fn"), [("median", np.median), ("mean", np.mean)])
def test_variance_test_is_anova_of_absolute_deviations(center, fn):
    d = _data(np.random.default_rng(23), sds=(0.1, 0.3, 0.2, 0.6))
    res = variance_test(d, "kc", "shape", center=center)
    dev = d.assign(z=d.groupby("shape")["kc"].transform(lambda s: (s - fn(s)).abs()))
    ref = anova_oneway(dev, "z", "shape")
    assert res.statistic == pytest.approx(ref.loc["between", "F"], rel=1e-9)
    assert res.p_value == pytest.approx(ref.loc["between", "PR(>F)"], rel=1e-8)
    assert (res.df_num, res.df_den) == (3, len(d) - 4)
    assert ("Brown" in res.test) == (center == "median")
    assert "F(3, 22)" in res.summary()


def test_variance_test_errors():
    d = _data(np.random.default_rng(24))
    with pytest.raises(StatisticsInputError, match="center"):
        variance_test(d, "kc", "shape", center="trimmed")
    single = pd.concat([d, pd.DataFrame({"shape": ["lonely"], "kc": [1.0]})])
    with pytest.raises(StatisticsInputError, match="at least 2 observations"):
        variance_test(single, "kc", "shape")


def test_welch_closed_form():
    d = _data(np.random.default_rng(25), sds=(0.1, 0.5, 0.2, 0.8))
    res = welch_anova(d, "kc", "shape")
    gs = _groups(d)
    k = len(gs)
    n = np.array([g.size for g in gs])
    m = np.array([g.mean() for g in gs])
    w = n / np.array([g.var(ddof=1) for g in gs])
    mw = (w * m).sum() / w.sum()
    lam = (((1 - w / w.sum()) ** 2) / (n - 1)).sum()
    f = ((w * (m - mw) ** 2).sum() / (k - 1)) / (1 + 2 * (k - 2) * lam / (k**2 - 1))
    df2 = (k**2 - 1) / (3 * lam)
    assert res.statistic == pytest.approx(f, rel=1e-9)
    assert res.df_den == pytest.approx(df2, rel=1e-9)
    assert res.p_value == pytest.approx(stats.f.sf(f, k - 1, df2), rel=1e-8)
    flat = d.assign(kc=d["kc"].where(d["shape"] != "s0", 1.0))
    with pytest.raises(StatisticsInputError, match="no scatter"):
        welch_anova(flat, "kc", "shape")


def test_scatter_table():
    d = _data(np.random.default_rng(26))
    d = pd.concat([d, pd.DataFrame({"shape": ["solo"], "kc": [1.5]})], ignore_index=True)
    t = scatter_table(d, "kc", "shape")
    g = d[d["shape"] == "s1"]["kc"]
    assert t.loc["s1", "n"] == len(g)
    assert t.loc["s1", "sd"] == pytest.approx(g.std(ddof=1))
    assert t.loc["s1", "cv"] == pytest.approx(g.std(ddof=1) / abs(g.mean()))
    assert np.isnan(t.loc["solo", "sd"]) and t.loc["solo", "n"] == 1
