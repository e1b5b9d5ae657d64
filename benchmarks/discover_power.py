"""Power and false findings of ``soilstats discover`` over many seeds (docs/discover.md).

Each situation of ``tests/discover_situations.py`` (an interaction, two causes at once, a
designed factor confounded with its test day, a drift over logged time, spikes and seating
offsets, load-terminated tests) is simulated with SEEDS seeds and discovered; the table gives
how often the planted situation was found as it should be (power) or, for artefacts and
outcomes, how often nothing was named.  ``--verbose`` prints what was named on each miss.

    python benchmarks/discover_power.py [SEEDS] [--verbose]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from discover_situations import SITUATIONS

from soilstats.discovery import discover


def main() -> None:
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    seeds = int(args[0]) if args else 20
    verbose = "--verbose" in sys.argv
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
