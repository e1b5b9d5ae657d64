"""Power and false findings of ``soilstats discover`` over many seeds (docs/discover.md).

Each situation of ``tests/discover_situations.py`` (an interaction, two causes at once, a
designed factor confounded with its test day, a drift over logged time, spikes and seating
offsets, load-terminated tests) is simulated with SEEDS seeds and discovered; the table gives
how often the planted situation was found as it should be (power) or, for artefacts and
outcomes, how often nothing was named.  ``--verbose`` prints what was named on each miss.
``--null N`` instead discovers the null campaigns (``NULL``: nothing planted, velocity,
operator, bin, moisture and grouser height crossed) of seeds 0..N-1 on two processes and
counts those with any finding (all false).

    python benchmarks/discover_power.py [SEEDS] [--verbose]
    python benchmarks/discover_power.py --null N [--verbose]
"""

from __future__ import annotations

import sys
import time
from multiprocessing import Pool
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from discover_situations import NULL, SITUATIONS

from soilstats.discovery import discover
from soilstats.simulation import simulate


def _null(seed: int) -> list[str]:
    result = discover(simulate(NULL, seed=seed).campaign, seed=0)
    return [f"{f.kind} / {f.cause} (Holm p = {f.p_adjusted:.3g})" for f in result.findings]


def null_rate(seeds: int, verbose: bool) -> None:
    start = time.perf_counter()
    with Pool(2) as pool:
        named = pool.map(_null, range(seeds), chunksize=4)
    false = [(seed, n) for seed, n in enumerate(named) if n]
    print(
        f"null campaigns, seeds 0-{seeds - 1}: {len(false)} of {seeds} gave a finding "
        f"({100 * len(false) / seeds:.1f} %), {(time.perf_counter() - start):.0f} s"
    )
    if verbose:
        for seed, n in false:
            print(f"    seed {seed}: {'; '.join(n)}")


def main() -> None:
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    verbose = "--verbose" in sys.argv
    if "--null" in sys.argv:
        null_rate(int(args[0]) if args else 200, verbose)
        return
    seeds = int(args[0]) if args else 20
    print(f"{'situation':<40} {'result':>22} {'s/campaign':>10}")
    for name, situation in SITUATIONS.items():
        good, start = 0, time.perf_counter()
        for seed in range(seeds):
            result = discover(situation.build(seed), seed=0)
            ok = bool(situation.judge(result))
            good += ok
            if verbose and not ok:
                named = [(f.cause, f.extension) for f in result.findings]
                print(f"    seed {seed}: named {named}; model {result.model()['extensions']}")
        what = "found" if situation.planted else "nothing named"
        per = (time.perf_counter() - start) / seeds
        print(f"{name:<40} {f'{what} {good}/{seeds}':>22} {per:>10.2f}")


if __name__ == "__main__":
    main()
