"""Every soilstats command in the README runs and exits without a warning it does not explain
(issue #47 item 6).

The commands are read from the README itself — code blocks and inline code — so a new
example is tested the day it is written. Each runs in a fresh folder as the reader would run
it; an output folder the README writes as a placeholder (DIR, D, OUT, reports/) is a folder
there. A command whose input is a placeholder (your campaign DIR, a SPEC or MAP file, NAME)
is a template, not an example: it is listed and checked to be one, not run.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

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


def _prepared(command: str) -> list[str] | None:
    """argv of ``command`` with placeholder output folders made real (None: a template)."""
    argv = shlex.split(command)
    for i, token in enumerate(argv):
        if argv[i - 1] == "--out" and token in OUT_PLACEHOLDERS:
            argv[i] = "out"
    if any(token in PLACEHOLDERS for token in argv):
        return None
    if len(argv) == 2 and argv[1] in {"study", "posterior", "wheel", "simulate", "import"}:
        return None  # the overview's bare names: each needs its input
    return argv


COMMANDS = readme_commands(README.read_text(encoding="utf-8"))


def test_the_readme_commands_are_found_and_templates_are_only_templates():
    runnable = [c for c in COMMANDS if _prepared(c) is not None]
    templates = [c for c in COMMANDS if _prepared(c) is None]
    assert any("posterior" in c for c in runnable), COMMANDS
    assert any(c.startswith("soilstats study velocity") for c in runnable), COMMANDS
    for t in templates:  # a template names an input the reader supplies
        assert set(shlex.split(t)) & PLACEHOLDERS or len(shlex.split(t)) == 2, t


def _warnings(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if re.search(r"warn", line, re.I)]


@pytest.mark.slow
@pytest.mark.parametrize(
    "command", [c for c in COMMANDS if _prepared(c) is not None], ids=lambda c: c[:60]
)
def test_every_readme_command_runs_clean(command, tmp_path):
    argv = _prepared(command)
    assert argv is not None
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONWARNINGS": "default"}
    done = subprocess.run(
        [sys.executable, "-m", "soilstats", *argv[1:]],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, (command, done.stderr[-2000:])
    assert not _warnings(done.stderr), (command, _warnings(done.stderr))
