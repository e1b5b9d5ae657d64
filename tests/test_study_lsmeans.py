"""Tukey pairs of a sinkage study on least-squares means of the blocked model.

The pairs decide the relevance verdicts (``no relevant effect`` needs every simultaneous
interval within the margin).  With operators spread unevenly over the levels, the pairs used
to compare means of a response with raw block means removed; that carries part of the
operator biases into the level differences.  The truth here is planted (operator biases,
level effects) and the reference is statsmodels' OLS fit of the same blocked model.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import statsmodels.formula.api as smf
from scipy.stats import studentized_range

from soilstats.statistics import tukey_hsd, tukey_lsmeans
from soilstats.study import load_spec
from soilstats.study.effects import factor_effects

SPEC = """
name = "unbalanced"
type = "sinkage"
factor = "velocity_m_s"
blocks = ["operator"]
model = "bernstein"
responses = [{ name = "log10_p_ref", margin = 0.3, margin_kind = "relative" }]
"""
# Level v1 mostly by operator A, v2 by B, v3 by C (the reviewer's design).
ALLOC = {
    0.001: {"A": 8, "B": 2, "C": 2},
    0.002: {"A": 2, "B": 8, "C": 2},
    0.003: {"A": 2, "B": 2, "C": 8},
}
BIAS = {"A": -0.10, "B": 0.0, "C": 0.10}  # log10 pressure per operator


def _unbalanced(rng, effect=None) -> pd.DataFrame:
    effect = effect or {}
    rows = [(v, o) for v, d in ALLOC.items() for o, n in d.items() for _ in range(n)]
    d = pd.DataFrame(rows, columns=["velocity_m_s", "operator"])
    d["log10_p_ref"] = (
        d["velocity_m_s"].map(lambda v: effect.get(v, 0.0))
        + d["operator"].map(BIAS)
        + 0.04 * rng.standard_normal(len(d))
    )
    return d.assign(soil="s")


@pytest.fixture(scope="module")
def spec(tmp_path_factory):
    path = tmp_path_factory.mktemp("spec") / "unbalanced.toml"
    path.write_text(SPEC)
    return load_spec(path)


def test_lsmeans_pairs_without_blocks_are_tukey_hsd():
    rng = np.random.default_rng(5)
    d = pd.DataFrame({"g": np.repeat(list("abcd"), [5, 7, 6, 9])})
    d["y"] = rng.standard_normal(len(d)) + d["g"].map({"a": 0, "b": 0.5, "c": 1, "d": 0})
    ls, ref = tukey_lsmeans(d, "y", "g"), tukey_hsd(d, "y", "g")
    cols = ["meandiff", "p_adj", "lower", "upper"]
    np.testing.assert_allclose(ls[cols].to_numpy(), ref[cols].to_numpy(), rtol=1e-9, atol=1e-12)
    assert (ls[["group1", "group2"]].to_numpy() == ref[["group1", "group2"]].to_numpy()).all()


def test_study_pairs_are_the_blocked_models_contrasts(spec):
    """The pairs of the study are the OLS contrasts of y ~ level + operator (statsmodels),
    with the Tukey–Kramer interval from the studentized range on the residual df."""
    d = _unbalanced(np.random.default_rng(11))
    pairs = factor_effects(d, spec, "s", 0.05)["pairs"]
    fit = smf.ols(
        "y ~ C(v) + C(operator)",
        d.rename(columns={"log10_p_ref": "y"}).assign(v=d["velocity_m_s"].astype(str)),
    ).fit()
    q = studentized_range.ppf(0.95, 3, fit.df_resid) / np.sqrt(2)
    for _, r in pairs.iterrows():
        c = np.zeros(len(fit.params))
        for group, sign in ((r["group2"], 1.0), (r["group1"], -1.0)):
            name = f"C(v)[T.{group}]"
            if name in fit.params.index:
                c[fit.params.index.get_loc(name)] += sign
        t = fit.t_test(c)
        est, se = float(t.effect[0]), float(t.sd[0, 0])
        assert r["meandiff"] == pytest.approx(est, abs=1e-12)
        assert r["upper"] - r["meandiff"] == pytest.approx(q * se, rel=1e-9)


@pytest.mark.slow  # many seeded studies: CI runs it
def test_unbalanced_operators_do_not_bias_the_pairs(spec):
    """Planted velocity effect 0 / +0.1 / +0.2 (log10 pressure), operator biases ±0.10 spread
    unevenly: removing raw operator means shrank the largest difference to ≈ 0.15 (the
    operators' means hold part of the level effect) and its intervals covered the truth in
    ≈ 56 % of runs; the least-squares pairs are unbiased and cover."""
    effect = {0.001: 0.0, 0.002: 0.1, 0.003: 0.2}
    rng = np.random.default_rng(2026)
    largest, covered = [], 0
    for _ in range(20):
        pairs = factor_effects(_unbalanced(rng, effect), spec, "s", 0.05)["pairs"]
        largest.append(pairs["meandiff"].abs().max())
        truth = pairs["group2"].astype(float).map(effect) - pairs["group1"].astype(float).map(
            effect
        )
        covered += bool(((pairs["lower"] <= truth) & (pairs["upper"] >= truth)).all())
    # sd of one difference ≈ 0.04·sqrt(2/12)·(design inflation) ≈ 0.02; the mean of 20 ≈ 0.005
    assert np.mean(largest) == pytest.approx(0.2, abs=0.02), np.mean(largest)
    assert covered >= 17  # Binomial(20, 0.95): P(≤ 16) ≈ 0.016


@pytest.mark.slow
def test_lsmeans_intervals_cover_planted_differences_at_their_level(spec):
    effect = {0.001: 0.0, 0.002: 0.1, 0.003: 0.2}
    rng = np.random.default_rng(7)
    runs, covered = 100, 0
    for _ in range(runs):
        pairs = factor_effects(_unbalanced(rng, effect), spec, "s", 0.05)["pairs"]
        truth = pairs["group2"].astype(float).map(effect) - pairs["group1"].astype(float).map(
            effect
        )
        covered += bool(((pairs["lower"] <= truth) & (pairs["upper"] >= truth)).all())
    # simultaneous 95 % (Tukey–Kramer, conservative): Binomial(100, 0.95) P(≤ 88) ≈ 0.004
    assert covered >= 89, covered
