"""Run time of ``soilstats discover`` on the bundled campaigns, step by step (issue #13).

Target: ≤ 10 s for the 962-test bundled ``simulated-paper`` campaign (interactive use), on
this machine's two cores, in one process as a user's command runs it.  The steps are timed
in one cold run each (load, data-quality screening, per-test fits and pooling, diagnosis with
interactions and power, extensions and forward selection); the whole ``discover`` call is
then repeated ROUNDS times on a fresh copy of the campaign (no screening cache) and the
median reported beside the target.

    python benchmarks/bench_discover.py [ROUNDS]
"""

from __future__ import annotations

import statistics
import sys
import time
from dataclasses import replace

import soilstats
from soilstats.discovery import discover
from soilstats.discovery.data import build_groups
from soilstats.discovery.diagnose import diagnose_groups
from soilstats.quality import screen

ROUNDS = int(sys.argv[1]) if len(sys.argv) > 1 else 3
CAMPAIGNS = {"simulated-paper": 10.0, "grc1-oravec2009": None, "cullinan-sand": None}


def _steps(name: str) -> dict[str, float]:
    times = {}
    t0 = time.perf_counter()
    campaign = soilstats.load_campaign(name)
    times["load"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    cleaned = screen(campaign).campaign
    times["screen"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    groups, _ = build_groups(cleaned)
    times["per-test fits + pooling"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    diagnose_groups(groups)
    times["diagnosis (main, interactions, power)"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    result = discover(cleaned, seed=0)
    times["discover, all steps (screened input)"] = time.perf_counter() - t0
    times["findings"] = len(result.findings)
    return times


def _whole(name: str) -> float:
    runs = []
    for _ in range(ROUNDS):
        campaign = soilstats.load_campaign(name)
        campaign = replace(campaign)  # a new object: the screening cache does not help
        t0 = time.perf_counter()
        discover(campaign, seed=0)
        runs.append(time.perf_counter() - t0)
    return statistics.median(runs)


def main() -> None:
    print(f"soilstats {soilstats.__version__}: discover, median of {ROUNDS} runs\n")
    for name, target in CAMPAIGNS.items():
        steps = _steps(name)
        tests = len(soilstats.load_campaign(name).tests)
        whole = _whole(name)
        verdict = "" if target is None else f"  target <= {target:g} s: " + (
            "met" if whole <= target else "NOT met"
        )
        print(f"{name} ({tests} tests, {steps.pop('findings')} findings): {whole:.2f} s{verdict}")
        for step, seconds in steps.items():
            print(f"    {step:<42} {seconds:6.2f} s")
        print()


if __name__ == "__main__":
    main()
