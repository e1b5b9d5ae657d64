"""Every script in benchmarks/ still runs: each in its ``--smoke`` mode (tiny sizes, seconds),
in a fresh process, as a user runs it (issue #45, item 5). A benchmark that crashes at HEAD
(``bench_identify.py`` did, for weeks) fails here; the numbers a smoke run prints mean
nothing and are not checked — timing lives in the benchmarks themselves.

Most smoke modes take more than a few seconds on two shared cores, so they are marked slow:
CI runs them (SOILSTATS_SLOW=1), a local ``pytest`` the quick ones.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "benchmarks"
SCRIPTS = sorted(p.name for p in BENCH.glob("*.py") if not p.name.startswith("_"))

#: Smoke modes that finish in a few seconds (the rest are marked slow).
QUICK = {"bench_startup.py", "bench_load_screen.py"}


def test_the_list_is_the_folder():
    assert len(SCRIPTS) >= 20 and "bench_identify.py" in SCRIPTS
    assert QUICK <= set(SCRIPTS)


@pytest.mark.parametrize(
    "script",
    [s if s in QUICK else pytest.param(s, marks=pytest.mark.slow) for s in SCRIPTS],
)
def test_every_benchmark_runs_in_its_smoke_mode(script, tmp_path):
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    env["MPLBACKEND"] = "Agg"
    run = subprocess.run(
        [sys.executable, str(BENCH / script), "--smoke"],
        cwd=tmp_path,  # a script that writes beside itself would leave files in the checkout
        env=env,
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert run.returncode == 0, f"{script} --smoke failed:\n{run.stderr[-3000:]}"
    assert run.stdout.strip(), f"{script} --smoke printed nothing"
    assert not list(tmp_path.iterdir()), list(tmp_path.iterdir())
