"""Parameter tables of the reports: value ± stderr with symbols and units.

One home for the two shapes every report prints: the paper's Table 5 (one row per
condition, one column per parameter) and one fit's parameters (one row per parameter).
``stderr`` is the test-level σ where a fit rests on five tests or more, Eq. 4's σ (the
paper's Eqs. 3–5) otherwise (docs/conventions.md); both shapes print Eq. 4's beside it.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ..identification.table import EQ4_MARK, format_value
from .document import Document, Markup
from .labels import natural_key, parameter_label, parameter_symbol

if TYPE_CHECKING:
    from ..discovery.testlevel import TestLevel
    from ..fitting.result import FitResult

__all__ = ["EQ4_NOTE", "condition_table", "fit_rows", "fit_table", "stderr_cell"]

#: What the cells of :func:`condition_table` mean, said once per report.
EQ4_NOTE = (
    "value ± stderr, the test-level σ (the sd over a bootstrap of the tests), with Eq. 4's σ "
    f"(the paper's Eqs. 3–5) in brackets; {EQ4_MARK}: the set rests on fewer than five tests "
    "and its ± is Eq. 4's σ, which leaves the scatter between tests out."
)


def short_number(value: float) -> str:
    """Two significant digits: 250, 22000, 0.0064; beyond 1e5 or below 1e-3 with an exponent
    without plus or leading zeros: 8.7e5, 1.2e-5."""
    rounded = float(f"{value:.2g}")
    if rounded == 0 or 1e-3 <= abs(rounded) < 1e5:
        return f"{rounded:.10g}"
    return re.sub(r"e\+?(-?)0*(\d)", r"e\1\2", f"{rounded:.2g}")


def stderr_cell(value: float, stderr: float, stderr_eq4: float | None, level: str | None) -> str:
    """``value ± stderr [Eq. 4's σ]`` where stderr is the test-level σ, ``value ± σ †`` where
    it is Eq. 4's, plain ``value ± σ`` where the level is not known."""
    cell = format_value(value, stderr)
    if level == "tests" and stderr_eq4 is not None and np.isfinite(stderr_eq4):
        return f"{cell} [{short_number(stderr_eq4)}]"
    if level == "eq4":
        return f"{cell} {EQ4_MARK}"
    return cell


def condition_table(
    doc: Document,
    conditions: Iterable[Mapping],
    *,
    caption: str,
    condition_label: str = "condition",
) -> None:
    """Table 5: one row per condition, ``value ± σ`` per parameter, then the extra columns.

    Each condition is a mapping with ``condition``, ``model``, ``params`` and ``stderr``
    (``{name: value}``), optionally ``stderr_eq4`` (``{name: value}``) and ``stderr_level``
    (``"tests"`` or ``"eq4"``, see :func:`stderr_cell`), ``units`` (``{name: unit}``) and any
    further columns in order (``epsilon``, ``tests``, ``health``, …). Rows are in natural
    condition order; a parameter a condition's model lacks prints as an en dash.
    """
    conditions = sorted(conditions, key=lambda c: natural_key(c["condition"]))
    names = list(dict.fromkeys(n for c in conditions for n in c["params"]))
    units = {n: u for c in conditions for n, u in c["units"].items()}
    fixed = {"condition", "model", "params", "stderr", "stderr_eq4", "stderr_level", "units"}
    rows = []
    for c in conditions:
        row = {"condition": c["condition"], "model": c["model"]}
        eq4 = c.get("stderr_eq4") or {}
        for n in names:
            row[n] = (
                stderr_cell(c["params"][n], c["stderr"][n], eq4.get(n), c.get("stderr_level"))
                if n in c["params"]
                else "–"
            )
        row |= {k: v for k, v in c.items() if k not in fixed}
        rows.append(row)
    labels: dict[str, str | Markup] = {n: parameter_label(n, units.get(n, "")) for n in names}
    labels |= {"condition": condition_label, "epsilon": parameter_symbol("epsilon")}
    doc.table(
        pd.DataFrame(rows),
        caption=caption,
        labels=labels,
        formats={"epsilon": ".3f", "tests": ".0f"},
        align_numbers=False,
    )


def fit_rows(
    fit: FitResult | None, level: TestLevel | None = None, *, units: str = "column"
) -> list[dict]:
    """One fit's parameters as rows ``{"parameter", "value ± σ", "unit"}`` (none without a
    fit; ``units="name"``: no unit column, the unit in brackets after the name): each cell
    a :func:`stderr_cell` of the σ discovery quotes
    (:func:`~soilstats.discovery.testlevel.quoted_sigma`: the test-level σ with Eq. 4's in
    brackets where five tests or more inform the parameter, Eq. 4's marked † otherwise), ``*``
    after it where the test-level σ exceeds Eq. 4's by more than 2× (``test-scatter``)."""
    if fit is None:
        return []
    from ..discovery.testlevel import quoted_sigma  # deferred: statsmodels (discovery's)

    stderr, eq4, levels = quoted_sigma(fit, level)
    hits = np.zeros(len(levels), bool) if level is None else level.flagged()
    rows = []
    for name, v, s, e, lv, hit in zip(
        fit.param_names, fit.values, stderr, eq4, levels, hits, strict=True
    ):
        unit = fit.units.get(name, "") or "–"
        cell = stderr_cell(v, s, e, lv) + (" *" if hit else "")
        if units == "name":
            label = name if unit in ("–", "-") else f"{name} ({unit})"
            rows.append({"parameter": label, "value ± σ": cell})
        else:
            rows.append({"parameter": name, "value ± σ": cell, "unit": unit})
    return rows


def fit_table(
    doc: Document,
    fit: FitResult | None,
    caption: str,
    level: TestLevel | None = None,
    *,
    units: str = "column",
    **table: Any,  # Document.table's keywords (small, widths), of their own types
) -> None:
    """One fit's parameters as ``value ± σ`` with units (nothing without a fit): the cells of
    :func:`fit_rows` (:data:`EQ4_NOTE` says what they mean, once per report); ``table``
    goes to :meth:`Document.table` (``small``, ``widths``)."""
    rows = fit_rows(fit, level, units=units)
    if rows:
        doc.table(pd.DataFrame(rows), caption=caption, align_numbers=False, **table)
