"""Every soilstats command in the README runs and exits without a warning it does not explain
(issue #47 item 6).

The commands are read from the README itself — code blocks and inline code — so a new
example is tested the day it is written. Each runs in a fresh folder as the reader would run
it; an output folder the README writes as a placeholder (DIR, D, OUT, reports/) is a folder
there. A command that reads what an earlier one wrote (``--calibration
reports/wheel_calibration.nc``) runs after it, in its folder, as one test. A command whose input
is a placeholder (your campaign DIR, a SPEC or MAP file, NAME) is a template, not an example:
it is listed and checked to be one, not run. The wheel's calibration chain runs in
tests/test_wheel_calibration_cli.py, whose CMU tests read what it writes.
"""

from __future__ import annotations

import shlex

import pytest
from readme_commands import (
    CHAINS,
    COMMANDS,
    PLACEHOLDERS,
    WHEEL_CHAIN,
    chains,
    prepared,
    readme_commands,
    run_readme_command,
    warning_lines,
)


def test_the_readme_commands_are_found_and_templates_are_only_templates():
    runnable = [c for c in COMMANDS if prepared(c) is not None]
    templates = [c for c in COMMANDS if prepared(c) is None]
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
    assert prepared(pair[1])[-3:] == ["out/wheel_calibration.nc", "--out", "mine/"]
    stderr = "Data quality (clean): ...\nwarning: a unit slip\nWARNING: pools 3 values\n"
    assert warning_lines(stderr) == ["warning: a unit slip", "WARNING: pools 3 values"]


@pytest.mark.slow
@pytest.mark.parametrize(
    "chain", [c for c in CHAINS if c is not WHEEL_CHAIN], ids=lambda chain: chain[0][:60]
)
def test_every_readme_command_runs_clean(chain, tmp_path):
    """Each chain in one folder: a later command reads what an earlier one wrote.  The wheel's
    chain runs in tests/test_wheel_calibration_cli.py (``WHEEL_CHAIN``), where its calibration
    is also the one the CMU held-out tests read."""
    for command in chain:
        run_readme_command(command, tmp_path)
