"""Start-up cost of soilstats: `import soilstats` and every `--help`, in fresh processes.

Targets (issue: fast start): `import soilstats` under 1 s, `soilstats --help` and every
`soilstats SUB --help` under 0.3 s. Each command runs in a new interpreter, as a user's does;
the median of ROUNDS runs is reported with the interpreter's own start-up for reference.

    python benchmarks/bench_startup.py [ROUNDS]
    python benchmarks/bench_startup.py --smoke      # one round, two commands (tests, CI)
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import time

from soilstats.cli.main import SUBCOMMANDS

SMOKE = sys.argv[1:] == ["--smoke"]
ROUNDS = 1 if SMOKE else int(sys.argv[1]) if len(sys.argv) > 1 else 7


def _median_seconds(argv: list[str]) -> tuple[float, int]:
    times, code = [], 0
    for _ in range(ROUNDS):
        start = time.perf_counter()
        run = subprocess.run(argv, capture_output=True, check=False)
        times.append(time.perf_counter() - start)
        code = run.returncode
    return statistics.median(times), code


def main() -> None:
    py = sys.executable
    cases = [
        ("python -c pass (interpreter only)", [py, "-c", "pass"], None),
        ("import soilstats", [py, "-c", "import soilstats"], 1.0),
        ("soilstats --help", [py, "-m", "soilstats", "--help"], 0.3),
    ]
    cases += [
        (f"soilstats {s} --help", [py, "-m", "soilstats", s, "--help"], 0.3)
        for s in list(SUBCOMMANDS)[: 1 if SMOKE else None]
    ]
    print(f"{'command':<36}{'median s':>10}{'target s':>10}{'exit':>6}  ok")
    for label, argv, target in cases:
        seconds, code = _median_seconds(argv)
        ok = "" if target is None else ("yes" if seconds < target and code == 0 else "NO")
        target_text = "-" if target is None else f"{target:.1f}"
        print(f"{label:<36}{seconds:>10.3f}{target_text:>10}{code:>6}  {ok}")


if __name__ == "__main__":
    main()
