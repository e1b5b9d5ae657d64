"""Statistical behaviour over many seeded simulations: planted effects are found, null data
give false positives near α (and Holm keeps the family-wise rate below α).

Binomial bounds: with R replicates at rate α the rate has sd √(α(1−α)/R); the bounds below are
about ±3.5 sd, so a correct implementation fails them with probability < 10⁻³.  Replicate
counts are kept small for speed (statsmodels formula fits cost ~15 ms each); the bounds are
wide enough to pass by chance rarely, and narrow enough to catch a wrong df or a wrong
denominator (which move the rate to 0.15 or more).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from soilstats.statistics import (
    ancova,
    anova_oneway,
    anova_twoway,
    tukey_hsd,
    variance_test,
    verdicts,
)

ALPHA = 0.05


def _groups(rng, means, n=6, sds=None):
    sds = sds or [1.0] * len(means)
    return pd.DataFrame(
        {
            "level": np.repeat([f"L{i}" for i in range(len(means))], n),
            "y": np.concatenate(
                [mu + sd * rng.standard_normal(n) for mu, sd in zip(means, sds, strict=True)]
            ),
        }
    )


def _rate(pvalues):
    return float(np.mean(np.asarray(pvalues) < ALPHA))


@pytest.mark.slow
def test_oneway_false_positive_rate_and_power():
    rng = np.random.default_rng(2024)
    null = [anova_oneway(_groups(rng, [0, 0, 0]), "y", "level").iloc[0, 4] for _ in range(500)]
    assert 0.016 <= _rate(null) <= 0.084
    big = [anova_oneway(_groups(rng, [0, 2, 4]), "y", "level").iloc[0, 4] for _ in range(60)]
    assert _rate(big) >= 0.95


@pytest.mark.slow
def test_holm_controls_family_wise_rate_over_soils_and_responses():
    """9 null tests (3 soils × 3 responses) per study: P(any significant) ≤ α after Holm.

    Null p-values are drawn uniform — what the test above shows the ANOVA delivers — so 1000
    studies cost one call (one family per study).
    """
    rng = np.random.default_rng(7)
    studies, tests = 1000, 9
    rows = pd.DataFrame(
        {
            "study": np.repeat(np.arange(studies), tests),
            "soil": np.tile(np.repeat(["soil01", "soil02", "soil03"], 3), studies),
            "response": np.tile(["kc", "kphi", "n"], 3 * studies),
            "factor": "velocity",
            "statistic": np.nan,
            "p_value": rng.uniform(size=studies * tests),
            "effect_size": np.nan,
            "test": "simulated null",
        }
    )
    v = verdicts(rows, alpha=ALPHA, family="study")
    fwer = v.groupby("study")["significant"].any().mean()
    unadjusted = (v["p_value"] < ALPHA).groupby(v["study"]).any().mean()
    assert fwer <= ALPHA + 0.025  # ~3.5 sd above α
    assert unadjusted > 0.3  # without control: 1 − 0.95⁹ ≈ 0.37


@pytest.mark.slow
def test_twoway_and_ancova_null_rates_and_power():
    rng = np.random.default_rng(99)
    p_two, p_two_effect, p_slope, p_int = [], [], [], []
    sigma = np.repeat([5.0, 15.0, 30.0], 2)
    for rep in range(100):
        d = pd.DataFrame(
            {
                "v": np.repeat(["a", "b", "c"], 8),
                "day": np.tile(["d1", "d2", "d3", "d4"], 6),
            }
        )
        block = d["day"].map({"d1": 0.0, "d2": 2.0, "d3": -1.0, "d4": 3.0})
        d["y"] = block + rng.standard_normal(len(d))
        p_two.append(anova_twoway(d, "y", "v", "day").loc["v", "PR(>F)"])
        if rep < 20:
            d["y"] = d["y"] + d["v"].map({"a": 0.0, "b": 2.0, "c": 4.0})
            p_two_effect.append(anova_twoway(d, "y", "v", "day").loc["v", "PR(>F)"])
        s = pd.DataFrame({"ring": np.repeat(["r1", "r2", "r3"], 6), "sigma": np.tile(sigma, 3)})
        s["tau"] = 2.0 + 0.6 * s["sigma"] + rng.standard_normal(len(s))
        res = ancova(s, "tau", "sigma", "ring")
        p_slope.append(res.slope_test.p_value)
        p_int.append(res.intercept_test.p_value)
    for p in (p_two, p_slope, p_int):
        assert 0.005 <= _rate(p) <= 0.125
    assert _rate(p_two_effect) >= 0.98


@pytest.mark.slow
def test_tukey_and_scatter_power_and_null():
    rng = np.random.default_rng(5)
    t = tukey_hsd(_groups(rng, [0, 0, 5], n=8), "y", "level")
    assert t.set_index(["group1", "group2"]).loc[("L0", "L1"), "reject"] == False  # noqa: E712
    assert t["reject"].sum() == 2
    p_null = [variance_test(_groups(rng, [0, 0, 0], n=8), "y", "level").p_value for _ in range(200)]
    assert _rate(p_null) <= ALPHA + 0.055
    spread = _groups(rng, [0, 0, 0], n=10, sds=[0.2, 1.0, 3.0])
    assert variance_test(spread, "y", "level").p_value < 0.01
