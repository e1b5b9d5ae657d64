"""Run time of ``soilstats discover``, step by step, and its ``--jobs`` speed-up (issue #15).

Targets: ``soilstats discover`` on the 962-test bundled ``simulated-paper`` campaign ≤ 5 s
(the whole command in a fresh process, as a user runs it: import, load, screening, per-test
fits, diagnosis, extensions and forward selection), on this machine's two cores; a simulated
10 000-test campaign ≤ 60 s with one job, and ≥ 1.7x faster with ``--jobs 2``.

Default: for each bundled campaign, the steps timed in one cold run each (load, screening,
per-test fits and pooling, diagnosis, the whole ``discover`` on the screened campaign), then
the whole command in a fresh process, median of ROUNDS runs, beside the target.

``--jobs CAMPAIGN``: ``soilstats discover --data CAMPAIGN --jobs 1`` and ``--jobs 2`` in fresh
processes, interleaved (ROUNDS each; the machine's other load hits both alike), their
medians, the speed-up, and whether the two JSON outputs are identical (they must be).

    python benchmarks/bench_discover.py [ROUNDS]
    python benchmarks/bench_discover.py [ROUNDS] --jobs /tmp/scale10
    python benchmarks/bench_discover.py --smoke     # GRC-1 once: that it runs (tests, CI)

A 10 000-test campaign: ``soilstats simulate SPEC --out /tmp/scale10 --seed 1`` with the
bundled campaign's spec (soilstats/data/simulated-paper/spec.toml) scaled up tenfold.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import time

import soilstats
from soilstats.discovery import discover
from soilstats.discovery.data import build_groups
from soilstats.discovery.diagnose import diagnose_groups
from soilstats.quality import screen

CAMPAIGNS = {"simulated-paper": 5.0, "grc1-oravec2009": None, "cullinan-sand": None}


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


def _command(data: str, *extra: str) -> tuple[float, str]:
    """Wall time of ``soilstats discover --json`` in a fresh process, and its JSON."""
    args = [sys.executable, "-m", "soilstats", "discover", "--data", data, "--json"]
    t0 = time.perf_counter()
    out = subprocess.run(
        [*args, "--progress", "off", *extra], capture_output=True, text=True, check=True
    )
    return time.perf_counter() - t0, out.stdout


def _without_command(text: str) -> dict:
    doc = json.loads(text)
    doc["provenance"].pop("command", None)  # the one field --jobs changes
    return doc


def bundled(rounds: int, campaigns: dict = CAMPAIGNS) -> None:
    print(f"soilstats {soilstats.__version__}: discover, median of {rounds} runs\n")
    for name, target in campaigns.items():
        steps = _steps(name)
        tests = len(soilstats.load_campaign(name).tests)
        whole = statistics.median(_command(name)[0] for _ in range(rounds))
        verdict = (
            ""
            if target is None
            else f"  target <= {target:g} s: " + ("met" if whole <= target else "NOT met")
        )
        print(
            f"{name} ({tests} tests, {steps.pop('findings')} findings): "
            f"soilstats discover {whole:.2f} s{verdict}"
        )
        for step, seconds in steps.items():
            print(f"    {step:<42} {seconds:6.2f} s")
        print()


def jobs(data: str, rounds: int) -> None:
    print(f"soilstats discover --data {data}: --jobs 1 against --jobs 2, {rounds} rounds\n")
    runs: dict[int, list[float]] = {1: [], 2: []}
    outputs: dict[int, dict] = {}
    for _ in range(rounds):
        for n in (1, 2):
            seconds, text = _command(data, "--jobs", str(n))
            runs[n].append(seconds)
            outputs[n] = _without_command(text)
            print(f"    --jobs {n}: {seconds:6.1f} s")
    one, two = (statistics.median(runs[n]) for n in (1, 2))
    same = "identical" if outputs[1] == outputs[2] else "DIFFERENT (a bug)"
    print(f"\nmedian --jobs 1 {one:.1f} s, --jobs 2 {two:.1f} s: {one / two:.2f}x; JSON {same}")


def main() -> None:
    args = sys.argv[1:]
    if args == ["--smoke"]:
        bundled(1, {"grc1-oravec2009": None})
        return
    rounds = int(args.pop(0)) if args and args[0].isdigit() else 3
    if args[:1] == ["--jobs"]:
        jobs(args[1], rounds)
    else:
        bundled(rounds)


if __name__ == "__main__":
    main()
