"""Benchmark: the test-level bootstrap — its cost, and whether its σ is honest.

1. Cost: 1,000 cluster-bootstrap resamples of the paper-size Bekker problem (3 plates × 10
   tests × 100 points; ``bench_identify.paper_size_campaign``), beside the loop a user would
   write instead (resample tests, ``scipy.optimize.curve_fit`` from the same start).
2. Coverage: over many simulated campaigns with preparation scatter (stiffness cv 0.15,
   n sd 0.04; 3 plates × 10 tests × 60 points: ``tests/posterior_calibration.population_spec``,
   as the slow test), the share of campaigns whose estimate lies
   within ±1σ of the centre, for Eq. 4's σ and for ``stderr_tests`` (200 resamples). The
   centre is the mean estimate over the campaigns (the σ's job is the estimator's spread);
   the share around the simulation's truth is printed beside it.

    python benchmarks/bench_bootstrap.py [--campaigns 200]

Ratios and shares from one run on this machine; not a unit test.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from bench_identify import paper_size_campaign
from scipy.optimize import curve_fit

from soilstats import BEKKER, fit_sinkage
from soilstats.identification import pool_sinkage
from soilstats.simulation import simulate

# The campaigns of the slow calibration test (tests/test_bootstrap.py), from one home.
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from posterior_calibration import PLATES, SOIL, population_spec


def _curve_fit_loop(campaign, resamples: int, seed: int, start) -> float:
    """Seconds for ``resamples`` cluster resamples refitted by curve_fit (the peer)."""
    pooled = pool_sinkage(campaign)
    b, z, p, w = pooled.x["b_m"], pooled.x["z_m"], pooled.y, pooled.weights
    index = pooled.test_index
    rows = [np.flatnonzero(index == t) for t in range(index.max() + 1)]
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    for _ in range(resamples):
        pick = np.concatenate([rows[t] for t in rng.integers(len(rows), size=len(rows))])
        curve_fit(
            lambda x, kc, kphi, n: BEKKER.func(x, kc, kphi, n),
            (b[pick], z[pick]),
            p[pick],
            p0=start,
            sigma=1 / w[pick],
            maxfev=2000,
        )
    return time.perf_counter() - t0


def cost(resamples: int = 1000) -> None:
    campaign = paper_size_campaign()
    base = fit_sinkage(campaign, "bekker", quality="off")
    t0 = time.perf_counter()
    with_bs = fit_sinkage(campaign, "bekker", quality="off", test_resamples=resamples, seed=1)
    ours = time.perf_counter() - t0
    t0 = time.perf_counter()
    fit_sinkage(campaign, "bekker", quality="off")
    plain = time.perf_counter() - t0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        peer = _curve_fit_loop(campaign, resamples, 1, base.values)
    print(f"Cost of {resamples} resamples, paper-size Bekker problem (3,000 samples, 30 tests):")
    print(
        f"  soilstats fit_sinkage(test_resamples={resamples}): {ours:.2f} s "
        f"(the fit alone {plain * 1e3:.0f} ms; bootstrap {ours - plain:.2f} s)"
    )
    print(
        f"  resample + scipy curve_fit loop:            {peer:.2f} s "
        f"-> soilstats {peer / max(ours - plain, 1e-9):.1f}x faster"
    )
    print(f"  {with_bs.bootstrap.n_failed} resamples not converged")


def coverage(campaigns: int) -> None:
    from tqdm import tqdm

    names = ("kc", "kphi", "n")
    est, eq4, tests = [], [], []
    for seed in tqdm(range(campaigns), desc="campaigns", leave=False):
        spec = population_spec(10, stiffness_cv=0.15, n_sd=0.04, points=60)
        camp = simulate(spec, seed=1000 + seed).campaign
        fit = fit_sinkage(camp, "bekker", quality="off", test_resamples=200, seed=seed)
        est.append(fit.params[list(names)].to_numpy())
        eq4.append(fit.stderr[list(names)].to_numpy())
        tests.append(fit.stderr_tests[list(names)].to_numpy())
    est, eq4, tests = map(np.array, (est, eq4, tests))
    centre = est.mean(axis=0)
    truth = np.array([SOIL[n] for n in names])
    print(
        f"\n1-sigma coverage over {campaigns} simulated campaigns "
        f"(stiffness cv 0.15, n sd 0.04; plates b = {PLATES} m x 10 tests x 60 points):"
    )
    print(
        f"  {'param':>6} {'Eq. 4':>8} {'stderr_tests':>13} {'(around truth)':>15}"
        f" {'sd of estimates':>16} {'mean stderr_tests':>18}"
    )
    for i, name in enumerate(names):
        inside_eq4 = np.mean(np.abs(est[:, i] - centre[i]) <= eq4[:, i])
        inside_tests = np.mean(np.abs(est[:, i] - centre[i]) <= tests[:, i])
        around_truth = np.mean(np.abs(est[:, i] - truth[i]) <= tests[:, i])
        print(
            f"  {name:>6} {inside_eq4:>8.0%} {inside_tests:>13.0%} {around_truth:>15.0%}"
            f" {est[:, i].std(ddof=1):>16.4g} {tests[:, i].mean():>18.4g}"
        )
    print(
        "  (target for a 1-sigma error bar: 68 %; binomial sd of the share "
        f"{np.sqrt(0.68 * 0.32 / campaigns):.0%})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--campaigns", type=int, default=200)
    parser.add_argument("--resamples", type=int, default=1000)
    parser.add_argument(
        "--smoke",
        action="store_true",
        help="tiny sizes, seconds: that it runs (tests/test_benchmarks.py)",
    )
    args = parser.parse_args()
    if args.smoke:
        args.campaigns, args.resamples = 3, 20
    cost(args.resamples)
    if args.campaigns > 0:
        coverage(args.campaigns)


if __name__ == "__main__":
    main()
