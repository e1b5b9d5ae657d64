"""Table-5-style parameter tables: value ± σ and ε for several conditions side by side."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from ..fitting.result import FitResult

__all__ = ["format_parameter_table", "format_value", "parameter_table"]


def format_value(value: float, sigma: float) -> str:
    """``value ± σ`` with σ to two significant digits and the value to the same decimal."""
    if not np.isfinite(sigma) or sigma <= 0:
        return f"{value:.4g} ± {sigma:.2g}"
    exponent = int(np.floor(np.log10(max(abs(value), sigma))))
    if -3 <= exponent < 5:
        decimals = max(0, 1 - int(np.floor(np.log10(sigma))))
        return f"{value:.{decimals}f} ± {sigma:.{decimals}f}"
    scale = 10.0**exponent
    digits = max(0, exponent - int(np.floor(np.log10(sigma))) + 1)
    return f"({value / scale:.{digits}f} ± {sigma / scale:.{digits}f})e{exponent}"


def parameter_table(fits: Mapping[str, FitResult]) -> pd.DataFrame:
    """Tidy table: one row per condition and parameter (value, stderr, unit, epsilon, n)."""
    rows = []
    for label, fit in fits.items():
        for name in fit.param_names:
            rows.append(
                {
                    "condition": label,
                    "parameter": name,
                    "value": fit.params[name],
                    "stderr": fit.stderr[name],
                    "unit": fit.units.get(name, ""),
                    "epsilon": fit.epsilon,
                    "tests": len(fit.tests) if fit.tests is not None else np.nan,
                    "flags": "; ".join(flag.code for flag in fit.flags),
                }
            )
    return pd.DataFrame(rows)


def format_parameter_table(fits: Mapping[str, FitResult], title: str = "") -> str:
    """Render ``fits`` as the paper's Table 5: parameters in rows, conditions in columns."""
    labels = list(fits)
    first = next(iter(fits.values()))
    names = first.param_names
    header = ["parameter", *labels]
    body = []
    for name in names:
        unit = first.units.get(name, "")
        body.append(
            [
                f"{name} [{unit}]",
                *(format_value(fits[c].params[name], fits[c].stderr[name]) for c in labels),
            ]
        )
    body.append(["epsilon (Eq. 2)", *(f"{fits[c].epsilon:.3f}" for c in labels)])
    body.append(
        [
            "tests",
            *(str(len(fits[c].tests)) if fits[c].tests is not None else "-" for c in labels),
        ]
    )
    body.append(
        [
            "health",
            *(
                "ok" if fits[c].healthy else ",".join(sorted({f.code for f in fits[c].flags}))
                for c in labels
            ),
        ]
    )
    widths = [max(len(row[i]) for row in [header, *body]) for i in range(len(header))]
    line = "  ".join("-" * w for w in widths)
    out = [title] if title else []
    out.append("  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)))
    out.append(line)
    out.extend(
        "  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)) for row in body
    )
    return "\n".join(out)
