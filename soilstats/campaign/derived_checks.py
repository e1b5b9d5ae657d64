"""Derived quantities of a valid campaign that are still not usable numbers, per test.

Every input may be a finite number and a quantity computed from it still not be (an area of
0 in float64, an infinite pressure); :func:`derived_issues` refuses such a test naming the
derived column. Split from :mod:`soilstats.campaign.validate` (the rules of the cells).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ._cells import first_per_key
from .validate import Issue

__all__ = ["derived_issues"]


#: The largest magnitude a derived sample quantity may have. Fits square residuals and
#: pressures; beyond ~1.3e154 the square is inf in float64 and the fit fails in a linear
#: algebra routine's words (a force of 1e303 N: "Eigenvalues did not converge"). No
#: Bevameter reading comes within a hundred orders of magnitude of this.
MAX_MAGNITUDE = 1e150


def _why(value: float) -> str:
    if np.isfinite(value):
        return (
            f"beyond ±{MAX_MAGNITUDE:g}, where a fit's squares overflow float64; no soil gives "
            "this (a unit or column mistake, or a corrupted cell?)"
        )
    return "not a finite number"


#: Derived test columns that must be positive and finite: kind of test, what it is, the
#: columns it is computed from, what an infinite or zero value would do.
_TEST_QUANTITIES = (
    ("area_m2", "sinkage", "the plate area", "every pressure of the test would be infinite"),
    ("aspect_ratio", "sinkage", "the aspect ratio length_m / width_m", "b and l/b are unusable"),
    (
        "ring_area_m2",
        "shear",
        "the ring area π (r_outer_m² − r_inner_m²)",
        "every σ would be infinite",
    ),
)
#: Derived sample columns that must be finite: how each is computed, from which column.
_SAMPLE_QUANTITIES = {
    "sinkage": (("pressure_Pa", "p = force_N / area_m2 (Eq. 6)", "force_N"),),
    "shear": (
        ("sigma_Pa", "σ = normal_force_N / ring_area_m2", "normal_force_N"),
        ("tau_Pa", "τ = 3 torque_Nm / (2π (r_outer_m³ − r_inner_m³)) (Eq. 12)", "torque_Nm"),
        ("j_m", "j = (r_outer_m + r_inner_m) / 2 · angle_rad (Eq. 14)", "angle_rad"),
    ),
}


def _geometry(tests: pd.DataFrame, i: int | np.integer, column: str) -> str:
    """The log values a derived test quantity is computed from, for a message."""

    def v(c: str) -> str:
        return f"{c} {float(tests[c].iloc[i])!r}" if c in tests.columns else f"{c} (none)"

    if column == "ring_area_m2":
        return f"{v('r_inner_m')}, {v('r_outer_m')}"
    if column == "area_m2" and tests["shape"].iloc[i] == "circle":
        return v("radius_m")
    return f"{v('width_m')}, {v('length_m')}"


def derived_issues(tables: dict[str, pd.DataFrame], names: dict[str, str]) -> list[Issue]:
    """Finite inputs whose derived quantities are not finite (or beyond ±MAX_MAGNITUDE), as
    per-test issues.

    Every input may be a finite number and the quantity computed from them still not be:
    a radius of 1e-200 m gives an area of 0 in float64 and infinite pressures; a force of
    1e308 N on a small plate, an infinite pressure. Such a value would reach every fit as
    ``inf``; the test is refused, with the derived column named (``area_m2``,
    ``pressure_Pa``, ...).

    Parameters
    ----------
    tables : dict
        ``tests``, ``sinkage``, ``shear`` with their derived columns; the index of each is
        the 0-based data row of its file.
    names : dict
        File stem → file name for messages.

    Returns
    -------
    list of Issue
        One per test and quantity (at its first row), in file order: log, sinkage, shear. A
        test refused for its geometry is not checked again for its samples.
    """
    tests = tables["tests"]
    ids = tests["test_id"].to_numpy(dtype=object)
    kind = tests["kind"].to_numpy(dtype=object)
    refused: set[str] = set()
    issues = []
    for column, applies, what, consequence in _TEST_QUANTITIES:
        values = tests[column].to_numpy(dtype=np.float64)
        with np.errstate(invalid="ignore"):
            bad = (kind == applies) & ~(np.isfinite(values) & (values > 0))
        for i in np.flatnonzero(bad):
            if ids[i] in refused:
                continue
            refused.add(ids[i])
            issues.append(
                Issue(
                    ids[i],
                    names["tests"],
                    column,
                    int(tests.index[i]) + 1,  # type: ignore[call-overload]  # pandas-stubs: Index[numpy int] is valid
                    f"{what} is {float(values[i])!r} in float64 for {_geometry(tests, i, column)}"
                    f" — not a positive finite number, so {consequence}; check the values "
                    "(metres)",
                )
            )
    for stem, quantities in _SAMPLE_QUANTITIES.items():
        table = tables[stem]
        for column, formula, source in quantities:
            values = table[column].to_numpy(dtype=np.float64)
            bad = ~(np.abs(values) <= MAX_MAGNITUDE)  # NaN and ±inf too
            if not bad.any():  # the common case: no id of a million samples is looked at
                continue
            bad &= ~table["test_id"].isin(refused).to_numpy(dtype=bool)
            sample_ids = table["test_id"].to_numpy(dtype=object)
            for pos, key, count in first_per_key(sample_ids, bad):
                more = f" ({count} rows of this test have this problem)" if count > 1 else ""
                issues.append(
                    Issue(
                        key,
                        names[stem],
                        column,
                        int(table.index[pos]) + 1,
                        f"{formula} is {float(values[pos])!r} in float64 for {source} "
                        f"{float(table[source].iloc[pos])!r} — {_why(values[pos])}; check "
                        f"{source} and the test's geometry in {names['tests']} (SI units){more}",
                    )
                )
    return issues
