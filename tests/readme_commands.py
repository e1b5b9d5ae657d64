"""The README's ``soilstats`` commands, read from the README itself, and how a test runs one
(issue #47 item 6): shared by tests/test_readme_commands.py, which runs them, and
tests/test_wheel_calibration_cli.py, whose CMU calibration *is* the README's ``--calibrate``
command, so the suite pays for that calibration once."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"

#: Inputs the reader must supply: a command holding one of these is a template.
PLACEHOLDERS = {"DIR", "NAME", "SPEC", "SPEC.toml", "MAP.toml", "my-campaign/", "wheel.csv"}
#: Output folders the README names as placeholders: replaced by a real folder.
OUT_PLACEHOLDERS = {"DIR", "D", "OUT", "reports/"}


def readme_commands(text: str) -> list[str]:
    """Every ``soilstats …`` command of the README: lines of code blocks (continuations
    joined, comments dropped) and inline code spans that start with ``soilstats``."""
    found: list[str] = []
    for block in re.findall(r"```(?:text|bash)\n(.*?)```", text, flags=re.S):
        joined = re.sub(r"\\\n\s*", " ", block)
        for line in joined.splitlines():
            line = line.split("#", 1)[0].strip()
            for part in line.split("&&"):
                part = part.strip()
                if part.startswith("soilstats "):
                    found.append(part)
    prose = re.sub(r"```.*?```", "", text, flags=re.S)
    for span in re.findall(r"`(soilstats [^`]+)`", prose.replace("\n", " ")):
        found.append(re.sub(r"\s+", " ", span).strip())
    out: list[str] = []
    for command in found:
        if command not in out:
            out.append(command)
    return out


def prepared(command: str) -> list[str] | None:
    """argv of ``command`` with placeholder output folders made real (None: a template): the
    folder after ``--out`` and a path read from inside one (``reports/x.nc``)."""
    argv = shlex.split(command)
    for i, token in enumerate(argv):
        if argv[i - 1] == "--out" and token in OUT_PLACEHOLDERS:
            argv[i] = "out"
        elif i and "/" in token.rstrip("/") and token.split("/")[0] + "/" in OUT_PLACEHOLDERS:
            argv[i] = "out/" + token.split("/", 1)[1]
    if any(token in PLACEHOLDERS for token in argv):
        return None
    if len(argv) == 2 and argv[1] in {"study", "posterior", "wheel", "simulate", "import"}:
        return None  # the overview's bare names: each needs its input
    return argv


def out_folder(argv: list[str]) -> str | None:
    return argv[argv.index("--out") + 1].rstrip("/") if "--out" in argv[:-1] else None


def chains(commands: list[str]) -> list[list[str]]:
    """The runnable commands in README order, each a chain of its own, except one that reads
    a path inside the folder an earlier command wrote (``--out``): it joins that command's
    chain, to run after it in one folder."""
    out: list[list[str]] = []
    writer: dict[str, int] = {}  # output folder -> the chain of its last writer
    for command in commands:
        argv = prepared(command)
        if argv is None:
            continue
        written = out_folder(argv)
        reads = [
            t.split("/")[0] for t in argv[1:] if "/" in t.rstrip("/") and t.rstrip("/") != written
        ]
        joined = [writer[f] for f in reads if f in writer]
        if joined:
            out[joined[-1]].append(command)
            index = joined[-1]
        else:
            out.append([command])
            index = len(out) - 1
        if written is not None:
            writer[written] = index
    return out


COMMANDS = readme_commands(README.read_text(encoding="utf-8"))
CHAINS = chains(COMMANDS)


def warning_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if re.search(r"warn", line, re.I)]


#: The README's chain that calibrates the wheel and applies it to a rover team's own wheel:
#: run by tests/test_wheel_calibration_cli.py, which checks the calibration it writes.
WHEEL_CHAIN = next(chain for chain in CHAINS if any("--calibrate" in c for c in chain))


def run_readme_command(command: str, folder: Path) -> subprocess.CompletedProcess:
    """Run one README ``command`` in ``folder`` as a reader would (``python -m soilstats``,
    Python's warnings shown) and assert that it exits 0 without a warning line."""
    argv = prepared(command)
    assert argv is not None, command
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONWARNINGS": "default"}
    done = subprocess.run(
        [sys.executable, "-m", "soilstats", *argv[1:]],
        cwd=folder,
        env=env,
        capture_output=True,
        text=True,
        timeout=1800,  # the wheel calibration: ~4 min alone, more on a shared CI machine
    )
    assert done.returncode == 0, (command, done.stderr[-2000:])
    assert not warning_lines(done.stderr), (command, warning_lines(done.stderr))
    return done
