"""Profiles of the two heaviest commands on the bundled campaign, written into docs/profiles/.

    python benchmarks/profile_commands.py

Runs ``soilstats study all`` and ``soilstats discover`` on the bundled ``simulated-paper``
campaign under cProfile, each in a fresh process as a user's command runs, and writes
``docs/profiles/study-all.txt`` and ``docs/profiles/discover.txt``: the wall time, then the
functions by cumulative and by own time (the 30 largest of each).  docs/performance.md
reads them.
"""

from __future__ import annotations

import io
import pstats
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "profiles"
COMMANDS = {
    "study-all": ["study", "all", "--progress", "off", "--overwrite"],
    "discover": ["discover", "--progress", "off"],
}


def profile(name: str, argv: list[str], folder: Path) -> str:
    stats_file = folder / f"{name}.prof"
    if argv[0] == "study":
        argv = [*argv, "--out", str(folder / "reports")]
    start = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "cProfile", "-o", str(stats_file), "-m", "soilstats", *argv],
        check=True,
        capture_output=True,
    )
    wall = time.perf_counter() - start
    text = io.StringIO()
    stats = pstats.Stats(str(stats_file), stream=text)
    stats.strip_dirs()
    text.write(f"soilstats {' '.join(argv[:-2] if argv[0] == 'study' else argv)}\n")
    text.write(f"wall time under cProfile: {wall:.1f} s (the profiler adds ~30 %)\n\n")
    text.write("== by cumulative time ==\n")
    stats.sort_stats("cumulative").print_stats(30)
    text.write("== by own time ==\n")
    stats.sort_stats("tottime").print_stats(30)
    return text.getvalue()


def main() -> None:
    if "--smoke" in sys.argv[1:]:  # discover on GRC-1, printed, docs/profiles untouched
        with tempfile.TemporaryDirectory() as tmp:
            text = profile(
                "discover", ["discover", "grc1-oravec2009", "--progress", "off"], Path(tmp)
            )
        print(text[:2000])
        return
    OUT.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name, argv in COMMANDS.items():
            text = profile(name, argv, Path(tmp))
            (OUT / f"{name}.txt").write_text(text)
            print(f"wrote {OUT / name}.txt")


if __name__ == "__main__":
    main()
