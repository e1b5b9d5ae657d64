"""Parameter tables of the reports: value ± σ (Eqs. 3–5) with symbols and units.

One home for the two shapes every report prints: the paper's Table 5 (one row per
condition, one column per parameter) and one fit's parameters (one row per parameter).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np
import pandas as pd

from ..identification.table import format_value
from .document import Document, Markup
from .labels import natural_key, parameter_label, parameter_symbol

__all__ = ["condition_table", "fit_table"]


def condition_table(
    doc: Document,
    conditions: Iterable[Mapping],
    *,
    caption: str,
    condition_label: str = "condition",
) -> None:
    """Table 5: one row per condition, ``value ± σ`` per parameter, then the extra columns.

    Each condition is a mapping with ``condition``, ``model``, ``params`` and ``stderr``
    (``{name: value}``), ``units`` (``{name: unit}``) and any further columns in order
    (``epsilon``, ``tests``, ``health``, …). Rows are in natural condition order; a
    parameter a condition's model lacks prints as an en dash.
    """
    conditions = sorted(conditions, key=lambda c: natural_key(c["condition"]))
    names = list(dict.fromkeys(n for c in conditions for n in c["params"]))
    units = {n: u for c in conditions for n, u in c["units"].items()}
    fixed = {"condition", "model", "params", "stderr", "units"}
    rows = []
    for c in conditions:
        row = {"condition": c["condition"], "model": c["model"]}
        for n in names:
            row[n] = format_value(c["params"][n], c["stderr"][n]) if n in c["params"] else "–"
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


def fit_table(doc: Document, fit, caption: str, level=None) -> None:
    """One fit's parameters as ``value ± σ`` with units (nothing without a fit).

    With ``level`` (discovery's :class:`~soilstats.discovery.testlevel.TestLevel`) a
    column gives the test-level σ (cluster-robust over tests, in the parameter's unit),
    ``*`` where it exceeds Eq. 4's by more than 2× (``test-scatter``: quote it), ``n/a``
    where one test alone sets the parameter."""
    if fit is None:
        return
    rows = [
        {"parameter": name, "value ± σ": format_value(v, s), "unit": fit.units.get(name, "") or "–"}
        for name, v, s in zip(fit.param_names, fit.values, fit.stderr_values, strict=True)
    ]
    if level is not None:
        for row, st, hit in zip(rows, level.stderr, level.flagged(), strict=True):
            row["test-level σ"] = f"{st:.3g}{' *' if hit else ''}" if np.isfinite(st) else "n/a"
        caption += (
            " Test-level σ: cluster-robust over tests; * exceeds Eq. 4's σ by more than 2× "
            "(test-scatter): quote it instead."
        )
    doc.table(pd.DataFrame(rows), caption=caption, align_numbers=False)
