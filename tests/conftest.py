"""Shared fixtures of the test suite."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pytest

# A small valid campaign with one test of each geometry, written as text cells exactly as a
# user's CSV would hold them. Rows of c1 are deliberately not contiguous.
_TESTS = [
    "test_id,kind,soil,repetition,shape,radius_m,width_m,length_m,velocity_m_s,"
    "r_inner_m,r_outer_m,grousers,grouser_height_m,omega_rpm,moisture_pct,bin",
    "c1,sinkage,loam,1,circle,0.05,,,0.01,,,,,,12.5,A",
    "r1,sinkage,loam,2,rectangle,,0.1,0.3,,,,,,,,B",
    "s1,shear,loam,1,,,,,,0.1,0.15,10,0.01,2.0,13,A",
]
_SINKAGE = [
    "test_id,z_m,force_N",
    "c1,-0.0001,-2.5",
    "c1,0.001,10",
    "r1,0.0,0.0",
    "c1,0.002,30.5",
    "r1,0.001,20",
]
_SHEAR = [
    "test_id,angle_rad,torque_Nm,normal_force_N",
    "s1,0.0,0.0,500",
    "s1,0.1,40,505",
]


# --- NIST StRD record (used by test_nist_*.py) ---------------------------------------------
NIST_RECORDS: list[tuple[str, str, str, float, float]] = []


@pytest.fixture
def nist_record() -> Callable[[tuple[str, str, str, float, float]], None]:
    """Record ``(kind, set name, start, digits a, digits b)`` of a NIST test for the report."""
    return NIST_RECORDS.append


# --- the slow statistical checks: CI runs them, a local `pytest` does not ------------------
#: Set to 1 (as .ci/run does) to run the tests marked ``slow`` too.
SLOW_ENV = "SOILSTATS_SLOW"


def pytest_collection_modifyitems(config, items):
    """Skip ``slow`` tests unless SOILSTATS_SLOW=1 or the run selects markers itself."""
    if os.environ.get(SLOW_ENV) == "1" or config.getoption("-m"):
        return
    skip = pytest.mark.skip(reason=f"slow statistical check: run with {SLOW_ENV}=1 (CI does)")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


def pytest_terminal_summary(terminalreporter):
    """Print the agreeing significant digits reached on every NIST StRD set."""
    if not NIST_RECORDS:
        return
    tr = terminalreporter
    tr.section("NIST StRD: log relative error (agreeing significant digits)")
    tr.write_line(f"{'kind':<10}{'data set':<10}{'start':<8}{'digits a':>10}{'digits b':>10}")
    for kind, name, start, a, b in sorted(NIST_RECORDS, key=str):
        tr.write_line(f"{kind:<10}{name:<10}{start:<8}{a:>10.1f}{b:>10.1f}")
    tr.write_line(
        "digits a/b: nonlinear and linear = parameters/std devs; anova = F/sums of squares. "
        f"{sum(r[2] != 'raised' for r in NIST_RECORDS)} reached certified values; "
        f"{sum(r[2] == 'raised' for r in NIST_RECORDS)} start-1 runs raised ConvergenceError."
    )


def _frame(lines: list[str]) -> pd.DataFrame:
    rows = [line.split(",") for line in lines]
    return pd.DataFrame(rows[1:], columns=rows[0], dtype=object)


@pytest.fixture
def campaign_frames() -> dict[str, pd.DataFrame]:
    """The small valid campaign as text frames: keys ``tests``, ``sinkage``, ``shear``."""
    return {"tests": _frame(_TESTS), "sinkage": _frame(_SINKAGE), "shear": _frame(_SHEAR)}


@pytest.fixture
def write_campaign(tmp_path: Path) -> Callable[..., Path]:
    """Factory: write frames (or raw CSV text) as a campaign folder and return its path.

    ``write_campaign(tests=..., sinkage=..., shear=..., name="c")``: a DataFrame is written
    as CSV without index, a str as the file's text, None leaves the file out.
    """

    def write(name: str = "campaign", **files: pd.DataFrame | str | None) -> Path:
        folder = tmp_path / name
        folder.mkdir()
        for stem, content in files.items():
            if content is None:
                continue
            path = folder / f"{stem}.csv"
            if isinstance(content, str):
                path.write_text(content, encoding="utf-8")
            else:
                content.to_csv(path, index=False)
        return folder

    return write
