"""The method effect of a preparation study with operators as a random sample.

Truth is planted in small per-test tables: persistent method × operator biases (the
simulator's ``operator_cv``) with no method effect, or a method effect.  References:
statsmodels' type II table of ``y ~ method * operator + plate``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import statsmodels.formula.api as smf
from scipy import stats
from statsmodels.stats.anova import anova_lm

from soilstats.errors import SpecError
from soilstats.statistics import welch_random_block
from soilstats.study import effects as effects_module
from soilstats.study import load_spec
from soilstats.study.effects import factor_effects

ONE_RESPONSE = """
name = "methods"
type = "sinkage"
factor = "preparation"
blocks = ["b_m", "operator"]
random_blocks = ["operator"]
model = "bernstein"
responses = ["log10_p_ref"]
"""


def _per_test(rng, *, methods=4, operators=3, reps=2, sd_inter=0.06, shift=0.0):
    """log10 p_ref per test: plates b_m 0.025/0.05/0.075 m (+0.1 log10 each), operator
    biases N(0, 0.05²), method × operator biases N(0, sd_inter²), scatter 0.04; method "1"
    shifted by ``shift``; n pure scatter."""
    op = 0.05 * rng.standard_normal(operators)
    inter = sd_inter * rng.standard_normal((methods, operators))
    rows = [
        dict(
            soil="s",
            preparation=str(m + 1),
            operator="ABCDE"[o],
            b_m=0.025 * (p + 1),
            log10_p_ref=(shift if m == 0 else 0.0) + op[o] + inter[m, o] + 0.1 * p,
        )
        for m in range(methods)
        for o in range(operators)
        for p in range(3)
        for _ in range(reps)
    ]
    d = pd.DataFrame(rows)
    d["log10_p_ref"] += 0.04 * rng.standard_normal(len(d))
    d["n"] = 0.8 + 0.02 * rng.standard_normal(len(d))
    return d


@pytest.fixture(scope="module")
def one_response(tmp_path_factory):
    path = tmp_path_factory.mktemp("spec") / "methods.toml"
    path.write_text(ONE_RESPONSE)
    return load_spec(path)


def test_operators_are_random_in_the_shipped_preparation_study_only(tmp_path):
    assert load_spec("preparation").random_blocks == ("operator",)
    assert load_spec("velocity").random_blocks == ()
    text = ONE_RESPONSE.replace('random_blocks = ["operator"]', "random_blocks = []")
    (tmp_path / "fixed.toml").write_text(text)
    assert load_spec(tmp_path / "fixed.toml").random_blocks == ()
    for bad, message in (('["session"]', "not one of blocks"), ('["b_m", "operator"]', "at most")):
        (tmp_path / "bad.toml").write_text(
            ONE_RESPONSE.replace('random_blocks = ["operator"]', f"random_blocks = {bad}")
        )
        with pytest.raises(SpecError, match=message):
            load_spec(tmp_path / "bad.toml")


def test_method_is_tested_against_method_by_operator():
    d = _per_test(np.random.default_rng(4))
    out = factor_effects(d, load_spec("preparation"), "s", 0.05)
    row = next(r for r in out["effects"] if r["response"] == "log10_p_ref")
    ref = anova_lm(smf.ols("log10_p_ref ~ C(preparation) * C(operator) + C(b_m)", d).fit(), typ=2)
    ms = ref["sum_sq"] / ref["df"]
    anova = out["anova"].query("response == 'log10_p_ref'").set_index("term")
    assert anova.loc["preparation", "F"] == pytest.approx(
        ms["C(preparation)"] / ms["C(preparation):C(operator)"], rel=1e-9
    )
    assert anova.loc["preparation", "error_term"] == "preparation:operator"
    assert row["error_term"] == "preparation:operator" and row["df_error"] == 6
    # ... and the Welch-type test with one variance per method (valid where the methods
    # scatter unequally, the pooled F where they scatter alike): the larger p decides.
    f = ms["C(preparation)"] / ms["C(preparation):C(operator)"]
    pooled_p = stats.f.sf(
        f, ref.loc["C(preparation)", "df"], ref.loc["C(preparation):C(operator)", "df"]
    )
    seed = effects_module._stream(0, "s", "log10_p_ref")  # the (soil, response) stream
    welch = welch_random_block(
        d, "log10_p_ref", "preparation", ["b_m", "operator"], "operator", seed=seed
    )
    assert welch.p_value != pytest.approx(pooled_p, rel=1e-3)  # two different tests
    assert row["p_value"] == pytest.approx(max(pooled_p, welch.p_value), rel=1e-9)
    assert anova.loc["preparation (one variance per level)", "F"] == welch.statistic
    assert "operator random" in row["test"] and "one variance per preparation" in row["test"]
    assert not out["notes"]


def test_untestable_designs_say_which_test_was_used(one_response):
    rng = np.random.default_rng(8)
    single = _per_test(rng).query("operator == 'A'")
    out = factor_effects(single, one_response, "s", 0.05)
    assert out["effects"][0]["error_term"] == "Residual"
    assert any("one operator only" in n and "test-to-test scatter" in n for n in out["notes"])

    no_log = _per_test(rng).drop(columns="operator")
    out = factor_effects(no_log, one_response, "s", 0.05)
    assert any("no 'operator' recorded" in n for n in out["notes"])

    # operator A prepares methods 1 and 2, B only method 2: no interaction to test against
    d = _per_test(rng, methods=2, operators=2)
    sparse = d[~((d["preparation"] == "1") & (d["operator"] == "B"))]
    out = factor_effects(sparse, one_response, "s", 0.05)
    assert out["effects"][0]["error_term"] == "Residual"
    assert any("may be read as a preparation effect" in n for n in out["notes"])

    # one test per method × operator cell (one plate): the residual is the interaction
    one = _per_test(rng, reps=1).query("b_m == 0.025")
    out = factor_effects(one, load_spec("preparation"), "s", 0.05)
    row = out["effects"][0]
    ref = anova_lm(smf.ols("log10_p_ref ~ C(preparation) + C(operator)", one).fit(), typ=2)
    assert row["statistic"] == pytest.approx(ref.loc["C(preparation)", "F"], rel=1e-9)
    assert any(
        "residual of the blocked ANOVA is the preparation × operator" in n for n in out["notes"]
    )


def test_planted_method_effect_is_found(one_response):
    # method 1 +0.5 log10 (× 3.2 pressure) against method × operator biases of sd 0.06.  The
    # verdict needs both the pooled F and the Welch-type test (one variance per method, from
    # 3 operators) to reject: at +0.3 log10 the Welch-type test alone finds the effect
    # (p < 0.05) in 0.85 of 1000 campaigns, the pooled F in 0.998 (docs/studies.md).
    for seed in range(3):
        d = _per_test(np.random.default_rng(100 + seed), shift=0.5)
        row = factor_effects(d, one_response, "s", 0.05)["effects"][0]
        assert row["p_value"] < 0.05, row


@pytest.mark.slow
def test_no_method_effect_gives_no_verdict_at_alpha(one_response):
    """Null method effect, method × operator biases sd 0.06 log10 (the bundled simulator's
    operator_cv 0.15 of method 9 is ≈ 0.065 log10): the study's method test stays at α (it
    rejected ≈ 50 % of these campaigns when the operators were fixed blocks)."""
    rng = np.random.default_rng(2028)
    runs = 100
    hits = sum(
        factor_effects(_per_test(rng), one_response, "s", 0.05)["effects"][0]["p_value"] < 0.05
        for _ in range(runs)
    )
    # Binomial(100, 0.05): P(≥ 13) < 10⁻³
    assert hits <= 12, hits
