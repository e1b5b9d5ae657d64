"""Table-5-style parameter tables: value ± σ and ε for several conditions side by side."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from ..fitting.result import FitResult

__all__ = ["format_parameter_table", "format_value", "parameter_table", "shown_stderr"]


def _sci(x: float, digits: int) -> str:
    """``x`` with ``digits`` significant digits, ``1.2e11`` rather than ``1.2e+11``."""
    text = f"{x:.{digits}g}"
    if "e" in text:
        mantissa, exp = text.split("e")
        text = f"{mantissa}e{int(exp)}"
    return text


def format_value(value: float, sigma: float) -> str:
    """``value ± σ`` with σ to two significant digits and the value to the same decimal.

    Where σ exceeds the value's size, each is printed on its own scale (``1.0e11 ± 1.4e13``):
    on the σ's decimal the value would read ``(0.0 ± 1.4)e13``, hiding it."""
    if not np.isfinite(sigma) or sigma <= 0:
        return f"{value:.4g} ± {sigma:.2g}"
    if sigma > abs(value) and value != 0:
        return f"{_sci(value, 2)} ± {_sci(sigma, 2)}"
    exponent = int(np.floor(np.log10(max(abs(value), sigma))))
    if -3 <= exponent < 5:
        decimals = max(0, 1 - int(np.floor(np.log10(sigma))))
        return f"{value:.{decimals}f} ± {sigma:.{decimals}f}"
    scale = 10.0**exponent
    digits = max(0, exponent - int(np.floor(np.log10(sigma))) + 1)
    return f"({value / scale:.{digits}f} ± {sigma / scale:.{digits}f})e{exponent}"


#: Marks a cell whose ± is Eq. 4's σ: its fit rests on fewer than five tests, so the scatter
#: between repeated tests could not be measured (see :func:`shown_stderr`).
EQ4_MARK = "†"
#: Marks a cell whose fit is flagged ``bootstrap-unstable``: no σ of it may be quoted.
UNSTABLE_MARK = "!"


def _unstable(fit: FitResult) -> bool:
    return any(f.code == "bootstrap-unstable" for f in fit.flags)


def _stderr_tests(fit: FitResult) -> pd.Series | None:
    return getattr(fit, "stderr_tests", None)


def _tests(fit: FitResult) -> pd.DataFrame | None:
    """The tests a campaign fit used (:attr:`CampaignFit.tests`); None for a fit without them,
    such as :func:`soilstats.fitting.identify`'s."""
    return getattr(fit, "tests", None)


def shown_stderr(fit: FitResult) -> tuple[pd.Series, bool]:
    """The σ a table shows beside the estimates (the fit's ``stderr``: test-level where it
    rests on five tests or more, docs/conventions.md), and whether it is Eq. 4's."""
    return fit.stderr, getattr(fit, "stderr_level", "eq4") != "tests"


def parameter_table(fits: Mapping[str, FitResult]) -> pd.DataFrame:
    """Tidy table: one row per condition and parameter (value, stderr — test-level where
    the fit rests on five tests or more —, stderr_eq4, stderr_level, stderr_tests where a
    test bootstrap ran, unit, epsilon, tests, flags)."""
    rows = []
    for label, fit in fits.items():
        tests_sd = _stderr_tests(fit)
        for name in fit.param_names:
            rows.append(
                {
                    "condition": label,
                    "parameter": name,
                    "value": fit.params[name],
                    "stderr": fit.stderr[name],
                    "stderr_eq4": fit.stderr_values[fit.param_names.index(name)],
                    "stderr_level": getattr(fit, "stderr_level", "eq4"),
                    "stderr_tests": np.nan if tests_sd is None else tests_sd[name],
                    "unit": fit.units.get(name, ""),
                    "epsilon": fit.epsilon,
                    "tests": np.nan if (tests := _tests(fit)) is None else len(tests),
                    "flags": "; ".join(flag.code for flag in fit.flags),
                }
            )
    return pd.DataFrame(rows)


def format_parameter_table(fits: Mapping[str, FitResult], title: str = "") -> str:
    """Render ``fits`` as the paper's Table 5: parameters in rows, conditions in columns.

    Each cell is value ± the fit's ``stderr``: the test-level σ where it rests on five tests
    or more, else Eq. 4's, marked ``†`` (:func:`shown_stderr`; a footnote says so); ``!``
    marks the cells of a fit flagged ``bootstrap-unstable``, whose σ that flag says not to
    quote."""
    labels = list(fits)
    first = next(iter(fits.values()))
    names = first.param_names
    header = ["parameter", *labels]
    shown = {c: shown_stderr(fits[c]) for c in labels}
    body = []
    for name in names:
        unit = first.units.get(name, "")
        body.append(
            [
                f"{name} [{unit}]",
                *(
                    format_value(fits[c].params[name], shown[c][0][name])
                    + (f" {EQ4_MARK}" if shown[c][1] else "")
                    + (f" {UNSTABLE_MARK}" if _unstable(fits[c]) else "")
                    for c in labels
                ),
            ]
        )
    body.append(["epsilon (Eq. 2)", *(f"{fits[c].epsilon:.3f}" for c in labels)])
    body.append(
        [
            "tests",
            *("-" if (tests := _tests(fits[c])) is None else str(len(tests)) for c in labels),
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
    eq4 = [c for c in labels if shown[c][1]]
    out.append(
        "± the test-level σ (bootstrap over the tests: what a new campaign of the same design "
        "scatters by)"
        + (
            f"; {EQ4_MARK} ± Eq. 4's σ: fewer than five tests, so the scatter between repeated "
            "tests could not be measured"
            if eq4
            else ""
        )
    )
    if any(_unstable(fits[c]) for c in labels):
        out.append(
            f"{UNSTABLE_MARK} bootstrap-unstable: the estimate depends on which tests are in the "
            "campaign; quote no σ of it (soilstats identify --verbose says why)"
        )
    return "\n".join(out)
