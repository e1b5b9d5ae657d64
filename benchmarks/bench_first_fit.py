"""A notebook user's first fit on new data: ``from_frames`` + ``fit_sinkage`` against a pandas
+ ``scipy.optimize.curve_fit`` script, each in a fresh process (issue #39, item 4).

Both read GRC-1's two CSV tables with pandas and fit a Bernstein law p = k z^n to the
51 mm plate's five tests. The soilstats side validates the campaign, judges its units once,
screens it (spikes, bursts, phases, contact, …), pools with Section 2.1's weights and fits by
the paper's LM with adequacy checks; the script fits the raw pressures with unit weights.
Timed inside each process (imports included, interpreter start-up excluded), best of
``--repeat`` fresh processes.

    python benchmarks/bench_first_fit.py

One run on this machine; the numbers are what it printed, not a unit test.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

DATA = Path(__file__).resolve().parents[1] / "soilstats" / "data" / "grc1-oravec2009"

SOILSTATS = f"""
import time
t0 = time.perf_counter()
import pandas as pd
import soilstats
from soilstats.campaign import Campaign
tests = pd.read_csv({str(DATA / "tests.csv")!r})
sinkage = pd.read_csv({str(DATA / "sinkage.csv")!r})
t1 = time.perf_counter()
campaign = Campaign.from_frames(tests, sinkage)
t2 = time.perf_counter()
fit = soilstats.fit_sinkage(campaign, "bernstein", radius_m=0.051)
t3 = time.perf_counter()
print(t3 - t0, t1 - t0, t2 - t1, t3 - t2, fit.params["n"])
"""

SCRIPT = f"""
import time
t0 = time.perf_counter()
import numpy as np
import pandas as pd
from scipy.optimize import curve_fit
tests = pd.read_csv({str(DATA / "tests.csv")!r})
sinkage = pd.read_csv({str(DATA / "sinkage.csv")!r})
t1 = time.perf_counter()
d = sinkage.merge(tests[["test_id", "radius_m"]], on="test_id")
d = d[(d["radius_m"] == 0.051) & (d["z_m"] > 0)]
p = d["force_N"] / (np.pi * d["radius_m"] ** 2)
t2 = time.perf_counter()
(k, n), _ = curve_fit(lambda z, k, n: k * z**n, d["z_m"].to_numpy(), p.to_numpy(), p0=[1e6, 1.0])
t3 = time.perf_counter()
print(t3 - t0, t1 - t0, t2 - t1, t3 - t2, n)
"""


def run(code: str) -> list[float]:
    out = subprocess.run(
        [sys.executable, "-c", code], check=True, capture_output=True, text=True
    ).stdout
    return [float(v) for v in out.split()]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="fresh processes each (5)")
    args = parser.parse_args()
    ours = min((run(SOILSTATS) for _ in range(args.repeat)), key=lambda r: r[0])
    theirs = min((run(SCRIPT) for _ in range(args.repeat)), key=lambda r: r[0])
    print(f"{'':<30}{'total s':>9}{'imports+read':>14}{'to data':>9}{'fit':>8}{'n':>8}")
    for name, r in (("soilstats from_frames + fit", ours), ("pandas + curve_fit", theirs)):
        print(f"{name:<30}{r[0]:>9.3f}{r[1]:>14.3f}{r[2]:>9.3f}{r[3]:>8.3f}{r[4]:>8.3f}")
    print(
        f"ratio soilstats / script: {ours[0] / theirs[0]:.1f}x in all, "
        f"{(ours[2] + ours[3]) / (theirs[2] + theirs[3]):.0f}x without imports and reading"
    )


if __name__ == "__main__":
    main()
