"""Verdicts with multiple-comparison control: Holm by hand, families, and input errors."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from soilstats.statistics import (
    VERDICT_COLUMNS,
    StatisticsInputError,
    TestResult,
    anova_oneway,
    anova_twoway,
    effect_row,
    verdicts,
)


def _rows(pvalues, soils=None):
    soils = soils or ["soil01"] * len(pvalues)
    return [
        {
            "soil": s,
            "response": f"r{i}",
            "factor": "velocity",
            "statistic": 1.0,
            "p_value": p,
            "effect_size": 0.1,
            "test": "one-way ANOVA",
        }
        for i, (s, p) in enumerate(zip(soils, pvalues, strict=True))
    ]


def _holm(p):
    """Holm's step-down adjusted p-values, written out: max over j ≤ i of (m − j)·p_(j)."""
    p = np.asarray(p)
    order = np.argsort(p)
    m = p.size
    adj = np.empty(m)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p[i]))
        adj[i] = running
    return adj


def test_holm_by_hand():
    p = [0.01, 0.04, 0.03, 0.005, 0.2]
    v = verdicts(_rows(p), alpha=0.05)
    assert list(v.columns) == VERDICT_COLUMNS
    np.testing.assert_allclose(v["p_adjusted"], _holm(p), rtol=1e-12)
    assert list(v["significant"]) == [True, False, False, True, False]
    assert v.attrs == {"alpha": 0.05, "method": "holm", "family": None, "n_tests": 5}
    bonf = verdicts(_rows(p), method="bonferroni")
    np.testing.assert_allclose(bonf["p_adjusted"], np.minimum(1, np.array(p) * 5))


def test_families_are_adjusted_separately_and_extra_columns_kept():
    p = [0.01, 0.04, 0.02, 0.03]
    rows = _rows(p, soils=["a", "a", "b", "b"])
    rows[0]["note"] = "first"
    v = verdicts(pd.DataFrame(rows), family="soil")
    np.testing.assert_allclose(v["p_adjusted"], [*_holm(p[:2]), *_holm(p[2:])], rtol=1e-12)
    assert list(v.columns) == [*VERDICT_COLUMNS, "note"]
    assert v.attrs["family"] == ["soil"]


@pytest.mark.parametrize(
    ("kwargs", "rows", "match"),
    [
        ({"alpha": 0}, _rows([0.1]), "alpha"),
        ({"method": "holmes"}, _rows([0.1]), "unknown method"),
        ({}, _rows([np.nan]), "missing or outside"),
        ({}, _rows([1.5]), "missing or outside"),
        ({}, [{"soil": "a", "p_value": 0.1}], "not in the effects"),
        ({"family": "operator"}, _rows([0.1]), "operator"),
    ],
)
def test_verdict_errors(kwargs, rows, match):
    with pytest.raises(StatisticsInputError, match=match):
        verdicts(rows, **kwargs)


def test_effect_row_from_tables_and_results():
    rng = np.random.default_rng(31)
    d = pd.DataFrame(
        {
            "v": np.repeat(["slow", "fast"], 8),
            "day": np.tile(["d1", "d2"], 8),
            "n": rng.normal(size=16),
        }
    )
    one = effect_row("soil01", "n", "v", anova_oneway(d, "n", "v"))
    two = effect_row("soil01", "n", "v", anova_twoway(d, "n", "v", "day"))
    res = TestResult("x", 2.0, 0.3, 1, 10, 0.2, "eta_sq")
    three = effect_row("soil02", "n", "v", res)
    assert one["test"] == "one-way ANOVA" and "type II" in two["test"]
    assert 0 <= one["effect_size"] <= 1 and three["p_value"] == 0.3
    v = verdicts([one, two, three])
    assert len(v) == 3 and v["p_adjusted"].ge(v["p_value"]).all()
    with pytest.raises(StatisticsInputError, match="no row 'speed'"):
        effect_row("s", "n", "speed", anova_twoway(d, "n", "v", "day"))


def test_holm_equals_statsmodels_multipletests():
    from statsmodels.stats.multitest import multipletests

    p = np.random.default_rng(32).uniform(0, 0.2, size=25)
    p[3] = p[7]  # a tie
    v = verdicts(_rows(list(p)), alpha=0.1)
    reject, ref, *_ = multipletests(p, alpha=0.1, method="holm")
    np.testing.assert_allclose(v["p_adjusted"], ref, rtol=1e-14)
    assert list(v["significant"]) == list(reject)


@pytest.mark.parametrize("method", ["holm", "fdr_bh", "bonferroni"])
def test_adjust_p_values_is_the_one_adjustment_and_equals_statsmodels(method):
    """The package's one p-value adjustment (verdicts and the preparation study call it):
    statsmodels' multipletests for every method, Holm written out to the last bits."""
    from statsmodels.stats.multitest import multipletests

    from soilstats.statistics import adjust_p_values

    p = np.random.default_rng(5).uniform(0, 0.3, size=17)
    p[[2, 9]] = p[4]  # ties
    ref = multipletests(p, alpha=0.05, method=method)[1]
    np.testing.assert_allclose(adjust_p_values(p, 0.05, method), ref, rtol=1e-14)
