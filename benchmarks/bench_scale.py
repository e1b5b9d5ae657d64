"""How soilstats scales: 100 → 1,000 → 10,000 tests (issue #15, item 3; item 4's --jobs).

A campaign of ~10,000 tests is simulated once from the bundled design (the paper's
``simulated-paper`` SPEC with every series' repetitions × 10: 9,620 tests, ~1.15 M samples;
about 120 samples per test as a 100 Hz rig logs a 1.2 s plate test), and seeded random
subsets of 100 and 1,000 of its tests are saved beside it, so every size has the same mix of
series.  Each size then runs in a *fresh process* (so peak memory is that size's own) through
the steps a user's commands take:

* load      — ``soilstats.load_campaign(folder)`` (CSV parsing and every format rule);
* screen    — ``soilstats.quality.screen`` (spikes, contact, load caps, drift …);
* identify  — every soil × series × condition of sinkage and shear, planned and fitted as
  one queue as the ``identify`` command does (``plan_conditions``, ``fit_planned``), with
  its default 200-resample test bootstrap;
* discover  — ``soilstats.discovery.discover`` on the screened campaign.

identify and discover run with ``jobs=1`` and ``jobs=2`` (worker processes, started before
the timings as the commands start them while loading; results are checked equal).  Peak
memory is the process's maximum resident set (ru_maxrss).  At the largest size the two
commands are then timed end to end (``soilstats identify|discover --jobs 1|2``: loading,
screening, the workers' start and the output included), and the speed-up this machine gives
two independent processes over one is measured (:func:`machine_ceiling`), the bound on any
2-job speed-up here.

    python benchmarks/bench_scale.py                 # all three sizes (~7 min on 2 cores)
    python benchmarks/bench_scale.py --sizes 100 1000

Targets at 10,000 tests: load ≤ 3 s, screen + identify ≤ 10 s, discover ≤ 60 s, peak
memory ≤ 2 GB, ≥ 1.7× speed-up with 2 jobs; each cost should grow linearly (×10 per ×10).
One run on this machine; the numbers are what it printed, not a unit test.
"""

from __future__ import annotations

import argparse
import itertools
import json
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SPEC = ROOT / "soilstats" / "data" / "simulated-paper" / "spec.toml"
TARGETS = {"load": 3.0, "screen + identify": 10.0, "discover": 60.0}


def build_campaigns(
    folder: Path, sizes: list[int], seed: int = 1, factor: int = 10
) -> dict[int, Path]:
    """The ×``factor`` campaign and seeded subsets of it, saved as campaign folders."""
    import numpy as np

    from soilstats.simulation import load_spec, simulate

    text = re.sub(
        r"^repetitions = (\d+)",
        lambda m: f"repetitions = {int(m.group(1)) * factor}",
        SPEC.read_text(),
        flags=re.M,
    )
    spec_file = folder / "spec-x10.toml"
    spec_file.write_text(text)
    full = simulate(load_spec(spec_file), seed=seed).campaign
    paths = {}
    rng = np.random.default_rng(seed)
    ids = full.tests["test_id"].to_numpy()
    for size in sizes:
        chosen = (
            full
            if size >= len(ids)
            else full.select(test_id=list(rng.choice(ids, size, replace=False)))
        )
        paths[size] = chosen.save(folder / f"tests-{size}", overwrite=True)
    return paths


def measure(folder: str) -> dict:
    """Run in a fresh process: the timings and peak memory of one campaign folder."""
    import soilstats
    from soilstats.discovery import discover
    from soilstats.identification.conditions import fit_planned, plan_conditions
    from soilstats.parallel import warm_workers
    from soilstats.quality import screen

    out: dict = {}
    # The workers' start (about a second) is no step's time: the commands overlap it with
    # loading the campaign (end-to-end command timings: commands()).
    warm_workers(2, ("soilstats.identification.conditions", "soilstats.discovery.pipeline")).join()
    t0 = time.perf_counter()
    campaign = soilstats.load_campaign(folder)
    out["load"] = time.perf_counter() - t0
    out["tests"] = len(campaign.tests)
    out["samples"] = len(campaign.sinkage) + len(campaign.shear)
    t0 = time.perf_counter()
    cleaned = screen(campaign).campaign
    out["screen"] = time.perf_counter() - t0
    summaries = {}
    for jobs in (1, 2):
        t0 = time.perf_counter()
        # As the identify command: both kinds planned, then fitted as one queue.
        plans = [
            plan_conditions(cleaned, kind, test_resamples=200, seed=0)
            for kind in ("sinkage", "shear")
            if (cleaned.tests["kind"] == kind).any()
        ]
        fits = fit_planned(plans, jobs=jobs)
        out[f"identify jobs={jobs}"] = time.perf_counter() - t0
        summaries[jobs] = [
            (f.fit.values.tolist(), f.fit.bootstrap and f.fit.bootstrap.draws.sum())
            for r in fits
            for f in r.fits
        ]
    out["identify equal for jobs 1, 2"] = summaries[1] == summaries[2]
    found = {}
    for jobs in (1, 2):
        t0 = time.perf_counter()
        kwargs = {"jobs": jobs} if jobs > 1 else {}
        result = discover(cleaned, seed=0, **kwargs)
        out[f"discover jobs={jobs}"] = time.perf_counter() - t0
        found[jobs] = re.sub(r"runtime [0-9.]+ s", "", result.summary())  # wall time
    out["discover equal for jobs 1, 2"] = found[1] == found[2]
    out["peak memory MB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return out


# The workload of the machine-ceiling check: paper-size Bekker fits, as a worker does them.
_CEILING_WORK = """
import sys, numpy as np
sys.path.insert(0, {bench!r})
from bench_identify import paper_size_campaign
import soilstats
from soilstats.parallel import one_blas_thread
campaign = paper_size_campaign()
with one_blas_thread():
    for _ in range(600):
        soilstats.fit_sinkage(campaign, "bekker")
"""


def machine_ceiling() -> float:
    """The speed-up this machine gives two independent processes over one: the same fixed
    fitting workload run alone, then two copies at once (fresh processes, BLAS on one thread
    each).  No parallel program can beat it; on a shared or virtual machine it is often
    well below 2."""
    code = _CEILING_WORK.format(bench=str(Path(__file__).parent))

    def run(copies: int) -> float:
        t0 = time.perf_counter()
        procs = [subprocess.Popen([sys.executable, "-c", code]) for _ in range(copies)]
        for proc in procs:
            if proc.wait() != 0:
                raise RuntimeError("the ceiling workload failed")
        return time.perf_counter() - t0

    one = min(run(1) for _ in range(2))
    two = min(run(2) for _ in range(2))
    return 2 * one / two


def commands(folder: Path) -> dict:
    """End-to-end wall time of ``soilstats identify`` and ``soilstats discover`` on
    ``folder`` with ``--jobs 1`` and ``--jobs 2`` (fresh processes: loading, screening,
    the workers' start and the output included — what a user waits for)."""
    out = {}
    for command in ("identify", "discover"):
        for jobs in (1, 2):
            argv = [sys.executable, "-m", "soilstats", command, "--data", str(folder)]
            argv += ["--jobs", str(jobs), "--json", "--progress", "off"]
            t0 = time.perf_counter()
            subprocess.run(argv, capture_output=True, check=True)
            out[f"{command} --jobs {jobs}"] = time.perf_counter() - t0
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 1000, 10000])
    parser.add_argument("--measure", help=argparse.SUPPRESS)  # internal: one fresh process
    parser.add_argument(
        "--smoke",
        action="store_true",
        help="tiny sizes, seconds: that it runs (tests/test_benchmarks.py)",
    )
    args = parser.parse_args()
    if args.smoke:
        args.sizes = [20]
    if args.measure:
        print(json.dumps(measure(args.measure)))
        return
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        paths = build_campaigns(Path(tmp), args.sizes, factor=1 if args.smoke else 10)
        print(f"simulated and saved the campaigns in {time.perf_counter() - t0:.1f} s")
        rows = {}
        for size, path in paths.items():
            run = subprocess.run(
                [sys.executable, __file__, "--measure", str(path)],
                capture_output=True,
                text=True,
                check=True,
            )
            rows[size] = json.loads(run.stdout.strip().splitlines()[-1])
            print(f"{size:>6} tests done", flush=True)
        ends = commands(paths[max(paths)])
    report(rows)
    print(f"\nCommands end to end at {rows[max(rows)]['tests']} tests (seconds):")
    for command in ("identify", "discover"):
        one, two = ends[f"{command} --jobs 1"], ends[f"{command} --jobs 2"]
        print(
            f"  soilstats {command:<9} --jobs 1 {one:6.2f}   --jobs 2 {two:6.2f}   x{one / two:.2f}"
        )
    if not args.smoke:  # three more interpreters that only measure the machine
        print(
            f"\n  machine ceiling: two independent processes run {machine_ceiling():.2f}x as "
            "fast as one (the bound on any 2-job speed-up here)"
        )


def report(rows: dict[int, dict]) -> None:
    import pandas as pd

    table = pd.DataFrame(rows).T
    for jobs in (1, 2):
        table[f"screen + identify jobs={jobs}"] = table["screen"] + table[f"identify jobs={jobs}"]
    steps = [
        "load",
        "screen",
        "identify jobs=1",
        "identify jobs=2",
        "screen + identify jobs=1",
        "screen + identify jobs=2",
        "discover jobs=1",
        "discover jobs=2",
        "peak memory MB",
    ]
    print("\nSeconds per step (one run each; fresh process per size):")
    print(table[["tests", "samples", *steps]].to_string(float_format=lambda v: f"{v:.2f}"))
    sizes = sorted(rows)
    print("\nGrowth per step (cost ratio between consecutive sizes; linear = the test ratio):")
    for a, b in itertools.pairwise(sizes):
        ratio = rows[b]["tests"] / rows[a]["tests"]
        growth = ", ".join(f"{s} x{rows[b][s] / rows[a][s]:.1f}" for s in steps[:3] + steps[6:7])
        print(f"  {rows[a]['tests']} -> {rows[b]['tests']} tests (x{ratio:.0f}): {growth}")
    big = rows[sizes[-1]]
    print(f"\nAt {big['tests']} tests ({big['samples']} samples):")
    best_identify = min(big["identify jobs=1"], big["identify jobs=2"])
    checks = [
        ("load", big["load"], TARGETS["load"]),
        ("screen + identify (best)", big["screen"] + best_identify, TARGETS["screen + identify"]),
        ("discover (best)", min(big["discover jobs=1"], big["discover jobs=2"]), 60.0),
        ("peak memory GB", big["peak memory MB"] / 1024, 2.0),
    ]
    for name, value, target in checks:
        verdict = "PASS" if value <= target else "FAIL"
        print(f"  {name:<28}{value:8.2f}  target <= {target:g}  {verdict}")
    for step in ("identify", "discover"):
        speedup = big[f"{step} jobs=1"] / big[f"{step} jobs=2"]
        verdict = "PASS" if speedup >= 1.7 else "FAIL"
        same = big[f"{step} equal for jobs 1, 2"]
        print(
            f"  {step} speed-up, 2 jobs     {speedup:8.2f}  target >= 1.7  {verdict}"
            f"  (results equal: {same})"
        )


if __name__ == "__main__":
    main()
