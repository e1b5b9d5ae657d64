"""Benchmark: ``soilstats wheel cmu-3d-terramechanics`` end to end, and its parts.

Target (issue #34): the default command on the bundled CMU campaign well under a minute on
the project machine (2 cores, shared).  Printed: the command as a user runs it (a fresh
process: imports, screening, sampling, 378 runs × 2000 draws through the wheel model, the
residual tests, 34 held-out fits, sensitivity, JSON, CSV and the typeset PDF), then the parts
in one process.

    python benchmarks/bench_wheel_validation.py            # prints the timings; not a test
    python benchmarks/bench_wheel_validation.py --smoke    # the parts at 200 draws, no command
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

from soilstats.campaign import load_campaign
from soilstats.data import bundled_path
from soilstats.quality import screen
from soilstats.wheel import plate_draws, validate_wheel

CMU = "cmu-3d-terramechanics"


def timed(label: str, fn):
    start = time.perf_counter()
    out = fn()
    print(f"{label:<62} {time.perf_counter() - start:6.2f} s")
    return out


def smoke() -> None:
    """``--smoke``: load, 200 plate draws and the prediction with its tests, no extension or
    sensitivity and no fresh command (tests/test_benchmarks.py): that it still runs."""
    runs = bundled_path(CMU) / "wheel.csv"
    campaign = timed("load and screen the plates", lambda: screen(load_campaign(CMU)).campaign)
    plate = timed("posterior, 200 draws", lambda: plate_draws(campaign, n_draws=200, seed=0))
    timed(
        "validate_wheel, prediction and tests only (no extension)",
        lambda: validate_wheel(campaign, runs, draws=plate, extension=False, sensitivity=False),
    )


def main() -> None:
    if "--smoke" in sys.argv[1:]:
        return smoke()
    with tempfile.TemporaryDirectory() as tmp:
        command = ["soilstats", "wheel", CMU, "--out", str(Path(tmp) / "w"), "--progress", "off"]
        timed(
            "soilstats wheel cmu-3d-terramechanics --out DIR (fresh process)",
            lambda: subprocess.run(command, check=True, capture_output=True),
        )
    runs = bundled_path(CMU) / "wheel.csv"
    campaign = timed("load and screen the plates", lambda: screen(load_campaign(CMU)).campaign)
    plate = timed("population posterior, 2000 draws", lambda: plate_draws(campaign, seed=0))
    timed(
        "validate_wheel, prediction and tests only (no extension)",
        lambda: validate_wheel(campaign, runs, draws=plate, extension=False, sensitivity=False),
    )
    timed(
        "validate_wheel, + slip extension and held-out gain",
        lambda: validate_wheel(campaign, runs, draws=plate, sensitivity=False),
    )
    timed("validate_wheel, everything (the default)", lambda: validate_wheel(campaign, runs))
    priors = {"phi": ("normal", 29, 4), "c": ("uniform", 0, 1500), "K": ("lognormal", 0.01, 0.8)}
    timed(
        "validate_wheel, everything, with shear priors (drawbar pull)",
        lambda: validate_wheel(campaign, runs, priors=priors),
    )


if __name__ == "__main__":
    sys.exit(main())
