"""Speed of the wheel calibration (issue #43): targets on two cores — the 54 β = 0 CMU runs
calibrated with a discrepancy term ≤ 60 s, all 378 runs ≤ 3 min, ``--predict`` ≤ 5 s.

    python benchmarks/bench_wheel_calibration.py            # the CMU runs, one run each
    python benchmarks/bench_wheel_calibration.py --smoke    # tiny sizes, seconds (CI)
    python benchmarks/bench_wheel_calibration.py --model    # one model call of the sampler only

``--model`` times what the calibration repeats ~10⁴ times: one model call
(:func:`soilstats.wheel.calibration.physics.simulate`) for P = 1 (least squares), 16 (half
of emcee's 32 walkers, what one differential-evolution step evaluates) and 32 parameter sets
on the 54 β = 0 CMU runs: CPU time per call, the least of 3 rounds (CPU time, as the machine
is shared; docs/performance.md, section 5).

Wall time of one run each (the calibration's own ``runtime_s`` is the sampler alone), and the
sampler's R-hat and ESS beside it: a fast calibration that did not converge is no result.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from soilstats import load_campaign
from soilstats.data import bundled_path
from soilstats.wheel import Wheel
from soilstats.wheel.calibration import RunDesign, calibrate_wheel
from soilstats.wheel.calibration.calibrate import _layout
from soilstats.wheel.calibration.physics import simulate
from soilstats.wheel.calibration.predict import predict_own_wheel
from soilstats.wheel.runs import read_runs, read_wheels, wheel_geometry
from soilstats.wheel.soil import plate_draws


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="tiny sizes, seconds")
    parser.add_argument("--model", action="store_true", help="time one model call only")
    args = parser.parse_args()
    folder = bundled_path("cmu-3d-terramechanics")
    runs = read_runs(folder / "wheel.csv")
    wheels = wheel_geometry(runs["wheel"].unique(), read_wheels(folder / "wheels.toml"))
    plates = plate_draws(load_campaign("cmu-3d-terramechanics"), n_draws=2000, seed=0)
    beta0 = runs[runs["beta_level"] == 0].reset_index(drop=True)
    if args.smoke:
        beta0 = beta0[beta0["wheel"] == "smooth"].iloc[::3].reset_index(drop=True)
    design = RunDesign.from_runs(beta0)
    if args.model:
        model_calls(design, wheels, plates.draws, plates.law)
        return
    draws = 400 if args.smoke else 8000
    t0 = time.perf_counter()
    cal = calibrate_wheel(design, wheels, plates.draws, plates.law, draws=draws, seed=0)
    wall = time.perf_counter() - t0
    print(
        f"calibration of {len(design)} β = 0 runs ({draws} draws): {wall:.1f} s wall "
        f"[target <= 60 s], R-hat {cal.rhat_max:.3f}, ESS {cal.ess_min:.0f}, "
        f"converged {cal.converged}"
    )
    t0 = time.perf_counter()
    pred = predict_own_wheel(
        Wheel(0.1, 0.08, name="own"),
        40.0,
        np.arange(-0.5, 0.91, 0.1),
        calibration=cal,
        wheel_amplitude={q: 0.005 if q == "sinkage_m" else 2.0 for q in cal.discrepancy},
        n_draws=200 if args.smoke else 2000,
        seed=0,
    )
    print(
        f"--predict with the calibration, {len(pred.draws)} draw × slip rows: "
        f"{time.perf_counter() - t0:.2f} s [target <= 5 s]"
    )


def model_calls(design: RunDesign, wheels: dict, draws, law: str) -> None:
    """CPU time of one model call for P parameter sets near the prior's centre (seeded)."""
    layout, shear, _ = _layout(design, draws, law, None, None, "plate posterior draws")
    rng = np.random.default_rng(0)
    for n_sets, reps in ((1, 300), (16, 100), (32, 60)):
        theta = layout.start() + 0.02 * rng.standard_normal((n_sets, layout.dim))
        params = layout.params(theta)
        best = np.inf
        for _ in range(3):
            t0 = time.process_time()
            for _ in range(reps):
                simulate(params, design, wheels, law, with_shear=shear)
            best = min(best, (time.process_time() - t0) / reps)
        print(
            f"model call, P = {n_sets:2d} parameter sets x {len(design)} runs: "
            f"{1e3 * best:.2f} ms CPU"
        )


if __name__ == "__main__":
    main()
