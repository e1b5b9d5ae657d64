"""Micro-benchmark: loading, screening and hashing a campaign (issue #15, 10,000 tests).

Times ``load_campaign``, ``quality.screen`` and the provenance digest ``campaign_sha256``,
each the median of a few runs, on the bundled campaign and on any campaign folders given.

    python benchmarks/bench_load_screen.py                    # bundled simulated-paper
    python benchmarks/bench_load_screen.py /tmp/scale10 -r 5  # and a folder, 5 runs each

A 10,000-test campaign to time: ``soilstats simulate SPEC --out /tmp/scale10 --seed 1``
with a specification scaled up from the bundled one (``repetitions`` ×10). Timings on a
shared machine are noisy: compare before/after in the same conditions and judge by ratios.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import soilstats
from soilstats.campaign.digest import campaign_sha256
from soilstats.quality import screen


def _median_seconds(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def _fresh_screen(campaign) -> None:
    # screen() caches findings by content within a process; a benchmark must not time the
    # cache, so it is emptied before every run.
    sys.modules["soilstats.quality.screen"]._FINDINGS.clear()
    screen(campaign)


def bench(source: str | Path, repeat: int) -> dict[str, float]:
    """Median seconds of load, screen and digest of one campaign."""
    campaign = soilstats.load_campaign(source)  # also warms imports and the file cache
    return {
        "tests": len(campaign.tests),
        "samples": len(campaign.sinkage) + len(campaign.shear),
        "load": _median_seconds(lambda: soilstats.load_campaign(source), repeat),
        "screen": _median_seconds(lambda: _fresh_screen(campaign), repeat),
        "sha256": _median_seconds(lambda: campaign_sha256(campaign), repeat),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="*", type=Path, help="campaign folders to time too")
    parser.add_argument("-r", "--repeat", type=int, default=3, help="runs per step (median)")
    parser.add_argument("--bundled", default="simulated-paper", help="bundled campaign name")
    parser.add_argument(
        "--smoke",
        action="store_true",
        help="tiny sizes, seconds: that it runs (tests/test_benchmarks.py)",
    )
    args = parser.parse_args(argv)
    if args.smoke:
        args.repeat, args.bundled = 1, "grc1-oravec2009"
    print(f"{'campaign':<28}{'tests':>7}{'samples':>10}{'load s':>9}{'screen s':>10}{'sha s':>8}")
    for source in [args.bundled, *args.folders]:
        r = bench(source, args.repeat)
        print(
            f"{source!s:<28}{r['tests']:>7}{r['samples']:>10}"
            f"{r['load']:>9.3f}{r['screen']:>10.3f}{r['sha256']:>8.3f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
