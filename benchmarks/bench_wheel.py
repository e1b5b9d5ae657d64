"""Benchmark: posterior draws × slips through the Wong–Reece wheel (soilstats.wheel).

Target (issue #34): 4,000 joint draws × 20 slips in ≤ 2 s on the project machine (2 cores,
shared).  Side by side, from the same run: the naive way — for each (draw, slip), scipy
``brentq`` on θ1 with ``quad`` for the load inside, then ``quad`` for drawbar pull and torque —
on a subset, as a time per case and a ratio, with the largest difference between the two.

    python benchmarks/bench_wheel.py            # prints the timings; not a unit test
    python benchmarks/bench_wheel.py --smoke    # 50 draws, one round: that it runs (tests, CI)

The naive loop calls the package's own (numpy) stress functions on scalars, so per-call
overhead is part of its cost: a loop written with ``math`` would be faster, the model the same.
The draws are synthetic (Bekker kc, kφ, n as a correlated normal around the GRC-1-like values
below; c, φ, K from stated priors), for a CMU-sized wheel (r = 58 mm, b = 50 mm) at W = 22 N.
"""

from __future__ import annotations

import sys
import time

import numpy as np
import pandas as pd
from scipy.integrate import quad
from scipy.optimize import brentq

from soilstats.bayes.stated_priors import sample_priors
from soilstats.wheel import StressAngles, Wheel, predict_wheel, wheel_forces
from soilstats.wheel.geometry import speed_ratio
from soilstats.wheel.stress import normal_stress, pressure_modulus, shear_displacement, shear_stress

WHEEL = Wheel(radius_m=0.058, width_m=0.05)
LOAD = 22.0
SLIPS = np.linspace(-0.9, 0.9, 20)
PRIORS = {"phi": ("normal", 30, 3), "c": ("uniform", 0, 1000), "K": ("lognormal", 0.01, 0.5)}
SMOKE = "--smoke" in sys.argv[1:]
N_DRAWS, N_NAIVE = (50, 1) if SMOKE else (4000, 5)


def synthetic_draws(n: int, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    mean = np.array([-2.0e3, 1.2e6, 1.0])
    sd = np.array([800.0, 1.0e5, 0.05])
    corr = np.array([[1.0, -0.6, 0.3], [-0.6, 1.0, -0.5], [0.3, -0.5, 1.0]])
    x = rng.multivariate_normal(mean, corr * np.outer(sd, sd), n)
    return pd.DataFrame(x, columns=["kc", "kphi", "n"])


def naive_case(row: dict, slip: float, angles: StressAngles) -> tuple[float, float, float]:
    """One (draw, slip) the textbook way: brentq on θ1 around quad integrals."""
    k_eq = pressure_modulus("bekker", row, WHEEL.width_m)
    n, rc, b = row["n"], WHEEL.contact_radius_m, WHEEL.width_m
    a_ratio, b_ratio = angles.ratios(slip)
    nu = speed_ratio(slip)

    def stresses(theta1):
        tm, t2 = a_ratio * theta1, b_ratio * theta1

        def sig(th):
            return normal_stress(th, theta1, tm, t2, k_eq, n, rc**n)

        def tau(th):
            j = shear_displacement(th, theta1, nu, WHEEL)
            return shear_stress(sig(th), j, row["c"], row["phi"], row["K"])

        return sig, tau, tm, t2

    def load(theta1):
        sig, tau, tm, t2 = stresses(theta1)
        f = quad(lambda th: sig(th) * np.cos(th) + tau(th) * np.sin(th), t2, theta1, points=[tm])
        return rc * b * f[0]

    theta1 = brentq(lambda t: load(t) - LOAD, 1e-6, 0.5 * np.pi, xtol=1e-12)
    sig, tau, tm, t2 = stresses(theta1)
    dp = (
        rc
        * b
        * quad(lambda th: tau(th) * np.cos(th) - sig(th) * np.sin(th), t2, theta1, points=[tm])[0]
    )
    torque = rc**2 * b * quad(tau, t2, theta1, points=[tm])[0]
    return rc * (1 - np.cos(theta1)), dp, torque


def main() -> None:
    draws = synthetic_draws(N_DRAWS)
    print(f"wheel: {WHEEL.describe()}, W = {LOAD} N, {N_DRAWS} draws x {len(SLIPS)} slips")
    times = []
    for _ in range(1 if SMOKE else 3):
        t0 = time.perf_counter()
        predict_wheel(draws, WHEEL, LOAD, SLIPS, priors=PRIORS, seed=1)
        times.append(time.perf_counter() - t0)
    print(
        f"predict_wheel (bands, samples, notes): first {times[0]:.2f} s, "
        f"best of 3 {min(times):.2f} s  [target <= 2 s]"
    )
    full = draws.assign(**sample_priors(PRIORS, len(draws), seed=1))  # what predict_wheel drew
    t0 = time.perf_counter()
    state = wheel_forces(full, WHEEL, SLIPS, law="bekker", load_N=LOAD)
    t_model = time.perf_counter() - t0
    cases = N_DRAWS * len(SLIPS)
    print(f"wheel_forces alone: {t_model:.2f} s = {1e6 * t_model / cases:.1f} us per (draw, slip)")

    subset = full.iloc[:N_NAIVE]
    angles = StressAngles()
    t0 = time.perf_counter()
    naive = np.array(
        [[naive_case(row, s, angles) for s in SLIPS] for row in subset.to_dict("records")]
    )
    t_naive = time.perf_counter() - t0
    per_naive = t_naive / naive[..., 0].size
    per_fast = t_model / cases
    print(
        f"naive quad + brentq loop on {N_NAIVE} draws x {len(SLIPS)} slips: {t_naive:.2f} s = "
        f"{1e6 * per_naive:.0f} us per case; vectorised is {per_naive / per_fast:.0f}x faster "
        f"per case (naive for all {cases} cases: ~{per_naive * cases:.0f} s)"
    )
    fast = np.stack(
        [state.sinkage_m[:N_NAIVE], state.drawbar_pull_N[:N_NAIVE], state.torque_Nm[:N_NAIVE]], -1
    )
    diff_z = np.max(np.abs(fast[..., 0] / naive[..., 0] - 1))
    diff_dp = np.max(np.abs(fast[..., 1] - naive[..., 1])) / LOAD
    diff_t = np.max(np.abs(fast[..., 2] / naive[..., 2] - 1))
    print(
        f"largest difference vectorised vs naive: sinkage {diff_z:.1e} (relative), drawbar pull "
        f"{diff_dp:.1e} of W, torque {diff_t:.1e} (relative)"
    )


if __name__ == "__main__":
    main()
