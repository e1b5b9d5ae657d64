"""False-alarm and detection rates of the ``zero-drift`` rule on simulated campaigns.

Each campaign: one soil (n = 0.45), three plates × N repetitions (default 6: 18 tests),
force noise and per-test sensor offsets of the simulator. A drift of ``step`` × the plate
series' median peak force per repetition is planted (repetition r reads (r - 1) × step too
high). Prints, per step: campaigns with any flag, the share of drifted tests (offset >= 1 %
of the peak) flagged, and how often the soil-level trend test alone (p < 0.01, before the
magnitude rules) fires (column trend).

    python benchmarks/drift_rates.py                  # 200 clean + 100 per step, seed 0..
    python benchmarks/drift_rates.py --campaigns 50 --repetitions 4
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
from test_quality_drift import drifted

from soilstats.quality import drift as drift_mod
from soilstats.quality import screen
from soilstats.quality.screen import _Records


def _trend_fires(campaign) -> bool:
    """The soil-level stratified Kendall test alone (no magnitude rule), plates as series."""
    rec = _Records.of(campaign.sinkage, ("z_m", "force_N"))
    z, force = rec.columns["z_m"], rec.columns["force_N"]
    starts = pd.Series(drift_mod.start_forces(rec.blocks, z, force), rec.ids)
    log = campaign.tests.assign(start=lambda t: t["test_id"].astype(str).map(starts))
    series = [g.sort_values("repetition")["start"].to_numpy() for _, g in log.groupby("b_m")]
    return drift_mod.kendall_p(series)[1] < drift_mod.DRIFT_ALPHA


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--campaigns", type=int, default=100)
    parser.add_argument("--repetitions", type=int, default=6)
    parser.add_argument(
        "--smoke",
        action="store_true",
        help="tiny sizes, seconds: that it runs (tests/test_benchmarks.py)",
    )
    args = parser.parse_args(argv)
    if args.smoke:
        args.campaigns = 2
    print(f"{'drift/test':>10} {'campaigns':>9} {'flagged':>8} {'tests hit':>9} {'trend':>6}")
    for step in (0.0, 0.0025, 0.005, 0.01, 0.02, 0.05):
        n = 2 * args.campaigns if step == 0 else args.campaigns
        any_flag = hit = due = trend = 0
        for seed in range(n):
            campaign = drifted(seed, step, args.repetitions)
            flagged = {f.test_id for f in screen(campaign).flags if f.code == "zero-drift"}
            any_flag += bool(flagged)
            reps = campaign.tests.set_index("test_id")["repetition"]
            drifted_tests = {t for t, r in reps.items() if step * (r - 1) >= 0.01 - 1e-12}
            hit += len(flagged & drifted_tests)
            due += len(drifted_tests)
            trend += _trend_fires(campaign)
        share = f"{hit / due:.0%}" if due else "-"
        print(f"{step:>10.2%} {n:>9} {any_flag:>8} {share:>9} {trend:>6}")


if __name__ == "__main__":
    main()
