"""Level and power of the preparation study's method verdicts (docs/studies.md).

Null campaigns of the bundled preparation design (``simulated-paper`` spec, series
``preparation`` and ``preparation-soil02``: 13 + 3 methods, 3 plates, 3 operators, 2 tests per
cell; velocity conditions and planted effects removed, so no method changes the mean; the
methods' scatter and operator biases as shipped), seeds 10000..10000+N-1, analysed as the
study does (per-test responses → ``factor_effects`` → Holm ``classify``; the pooled fits do
not enter the verdicts).  SHIFT (log10) is added to method 13's pressure at 25 mm on both
soils to measure power.  Prints the share of campaigns with any significant method verdict
and, per soil and response, the raw and Holm-adjusted rejection rates.

``--equal-scatter N SHIFT`` instead draws N small campaigns in which every method scatters
alike (``tests/test_study_operators.py::_per_test``: 4 methods, 3 operators, method ×
operator biases sd 0.06 log10, method 1 + SHIFT) and gives how often the Welch-type test,
the pooled F and the study's verdict (the larger of their p) find p < 0.05.

    python benchmarks/preparation_fpr.py N [SHIFT]
    python benchmarks/preparation_fpr.py --equal-scatter N SHIFT
"""

from __future__ import annotations

import copy
import sys
import time
import tomllib
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]  # this checkout's soilstats and test helpers

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from soilstats.simulation import simulate  # noqa: E402
from soilstats.statistics import anova_random_block, welch_random_block  # noqa: E402
from soilstats.study import load_spec  # noqa: E402
from soilstats.study.effects import factor_effects  # noqa: E402
from soilstats.study.responses import PerTestCache  # noqa: E402
from soilstats.study.verdict import classify  # noqa: E402


def bundled(n: int, shift: float) -> None:
    base = tomllib.loads((ROOT / "soilstats/data/simulated-paper/spec.toml").read_text())
    spec = load_spec(ROOT / "studies/preparation.toml")
    sim = copy.deepcopy(base)
    sim["series"] = [s for s in sim["series"] if s["name"] in ("preparation", "preparation-soil02")]
    for soil in sim["soils"].values():
        soil.pop("conditions", None)
    sim["effects"] = []
    rows, t0 = [], time.time()
    for seed in range(n):
        campaign = simulate(sim, seed=10_000 + seed).campaign
        ids = campaign.tests.test_id.astype(str).tolist()
        per_test = PerTestCache(campaign).sinkage(ids, spec.z_ref_m, spec.z_window_m)
        if shift:
            per_test.loc[per_test["preparation"].astype(str) == "13", "log10_p_ref"] += shift
        effects = []
        for soil in sorted(per_test["soil"].astype(str).unique()):
            one = per_test[per_test["soil"].astype(str) == soil]
            effects += factor_effects(one, spec, soil, spec.alpha)["effects"]
        rows.append(classify(effects, alpha=spec.alpha, family=spec.family).assign(seed=seed))
    a = pd.concat(rows, ignore_index=True)
    print(f"seeds={n} shift={shift} time={time.time() - t0:.0f}s test: {a['test'].iloc[0]}")
    print(f"  P(any significant per study) = {a.groupby('seed')['significant'].any().mean():.3f}")
    by = a.assign(raw=a["p_value"] < 0.05).groupby(["soil", "response"])
    print("  P(raw p < 0.05):", by["raw"].mean().round(3).to_dict())
    print("  P(significant after Holm):", by["significant"].mean().round(3).to_dict())


def equal_scatter(n: int, shift: float) -> None:
    from test_study_operators import _per_test

    rng = np.random.default_rng(5)
    blocks = ["b_m", "operator"]
    welch, pooled = [], []
    for _ in range(n):
        d = _per_test(rng, shift=shift)
        welch.append(
            welch_random_block(d, "log10_p_ref", "preparation", blocks, "operator").p_value
        )
        table = anova_random_block(d, "log10_p_ref", "preparation", blocks, "operator")
        pooled.append(table.loc["preparation", "PR(>F)"])
    welch, pooled = np.array(welch), np.array(pooled)
    print(
        f"equal scatter, {n} campaigns, shift {shift}: P(p < 0.05) Welch-type "
        f"{np.mean(welch < 0.05):.3f}, pooled F {np.mean(pooled < 0.05):.3f}, "
        f"the study's verdict (the larger p) {np.mean(np.maximum(welch, pooled) < 0.05):.3f}"
    )


if __name__ == "__main__":
    warnings.filterwarnings("ignore")
    if sys.argv[1] == "--smoke":  # one campaign of each: that it runs (tests, CI)
        bundled(1, 0.0)
        equal_scatter(2, 0.0)
    elif sys.argv[1] == "--equal-scatter":
        equal_scatter(int(sys.argv[2]), float(sys.argv[3]))
    else:
        bundled(int(sys.argv[1]), float(sys.argv[2]) if len(sys.argv) > 2 else 0.0)
