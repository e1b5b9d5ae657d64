"""Every soilstats command in the README runs and exits without a warning it does not explain
(issue #47 item 6).

The commands are read from the README itself — code blocks and inline code — so a new
example is tested the day it is written. Each runs in a fresh folder as the reader would run
it; an output folder the README writes as a placeholder (DIR, D, OUT, reports/) is a folder
there. A command that reads what an earlier one wrote (``--calibration
reports/wheel_calibration.nc``) runs after it, in its folder, as one test. A command whose input
is a placeholder (your campaign DIR, a SPEC or MAP file, NAME) is a template, not an example:
it is listed and checked to be one, not run.
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


def _out(argv: list[str]) -> str | None:
    return argv[argv.index("--out") + 1].rstrip("/") if "--out" in argv[:-1] else None


def chains(commands: list[str]) -> list[list[str]]:
    """The runnable commands in README order, each a chain of its own, except one that reads
    a path inside the folder an earlier command wrote (``--out``): it joins that command's
    chain, to run after it in one folder."""
    out: list[list[str]] = []
    writer: dict[str, int] = {}  # output folder -> the chain of its last writer
    for command in commands:
        argv = _prepared(command)
        if argv is None:
            continue
        written = _out(argv)
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


def test_the_readme_commands_are_found_and_templates_are_only_templates():
    runnable = [c for c in COMMANDS if _prepared(c) is not None]
    templates = [c for c in COMMANDS if _prepared(c) is None]
    assert any("posterior" in c for c in runnable), COMMANDS
    assert any(c.startswith("soilstats study velocity") for c in runnable), COMMANDS
    # the wheel's calibration and a rover team's own wheel from it run, in that order
    calibrate = [c for c in runnable if "--calibrate" in c]
    predict = [c for c in runnable if "--predict" in c]
    assert calibrate and predict, runnable
    assert [calibrate[0], predict[0]] in CHAINS, CHAINS
    assert sorted(c for chain in CHAINS for c in chain) == sorted(runnable)  # each runs once
    for t in templates:  # a template names an input the reader supplies
        assert set(shlex.split(t)) & PLACEHOLDERS or len(shlex.split(t)) == 2, t


def _warnings(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if re.search(r"warn", line, re.I)]


def test_the_check_itself_sees_a_new_command_and_its_warnings():
    """A command added to the README is collected (so a new, warning-producing example gets a
    test of its own), a command reading another's output joins its chain, and the CLI's
    warning lines (the library's ``warning:``, the commands' ``WARNING:``) are caught."""
    text = (
        "Run `soilstats identify --data grc1-oravec2009` first.\n\n```text\n"
        "soilstats check --data cullinan-sand   # screening\n"
        "soilstats wheel cmu-3d-terramechanics --calibrate --out reports/\n"
        "soilstats wheel cmu-3d-terramechanics --predict --calibration \\\n"
        "    reports/wheel_calibration.nc --out mine/\n```\n"
    )
    found = readme_commands(text)
    assert "soilstats check --data cullinan-sand" in found
    assert "soilstats identify --data grc1-oravec2009" in found
    chained = chains(found)
    assert sorted(map(len, chained)) == [1, 1, 2], chained
    pair = next(chain for chain in chained if len(chain) == 2)
    assert "--calibrate" in pair[0] and "--predict" in pair[1]
    assert _prepared(pair[1])[-3:] == ["out/wheel_calibration.nc", "--out", "mine/"]
    stderr = "Data quality (clean): ...\nwarning: a unit slip\nWARNING: pools 3 values\n"
    assert _warnings(stderr) == ["warning: a unit slip", "WARNING: pools 3 values"]


@pytest.mark.slow
@pytest.mark.parametrize("chain", CHAINS, ids=lambda chain: chain[0][:60])
def test_every_readme_command_runs_clean(chain, tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONWARNINGS": "default"}
    for command in chain:  # in one folder: a later command reads what an earlier one wrote
        argv = _prepared(command)
        assert argv is not None
        done = subprocess.run(
            [sys.executable, "-m", "soilstats", *argv[1:]],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=1800,  # the wheel calibration: ~7 min alone, more on a shared CI machine
        )
        assert done.returncode == 0, (command, done.stderr[-2000:])
        assert not _warnings(done.stderr), (command, _warnings(done.stderr))
