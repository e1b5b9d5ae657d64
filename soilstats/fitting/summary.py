"""The readable views of a fit: the text summary in the manner of lmfit and statsmodels, and
the HTML tables a notebook shows (what :meth:`FitResult.summary` and
:meth:`FitResult._repr_html_` return)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np
import pandas as pd

from .._html import facts_html, notes_html, result_html, table_html
from ..outputs.text import notes_block

__all__ = [
    "ShownFit",
    "fit_html",
    "fit_summary",
    "parameter_frame",
    "parameter_lines",
]


class ShownFit(Protocol):
    """What the views read of a fit (:class:`soilstats.fitting.result.FitResult`)."""

    @property
    def model_name(self) -> str: ...

    @property
    def param_names(self) -> tuple[str, ...]: ...

    @property
    def values(self) -> np.ndarray: ...

    @property
    def stderr_values(self) -> np.ndarray: ...

    @property
    def units(self) -> dict[str, str]: ...

    @property
    def method(self) -> str: ...

    @property
    def converged(self) -> bool: ...

    @property
    def message(self) -> str: ...

    @property
    def nobs(self) -> int: ...

    @property
    def dof(self) -> int: ...

    @property
    def nfev(self) -> int: ...

    @property
    def niter(self) -> int: ...

    @property
    def epsilon(self) -> float: ...

    @property
    def rss(self) -> float: ...

    @property
    def redchi(self) -> float: ...

    @property
    def aic(self) -> float: ...

    @property
    def bic(self) -> float: ...

    @property
    def jacobian_method(self) -> str: ...

    @property
    def condition_number(self) -> float: ...

    @property
    def params(self) -> pd.Series: ...

    @property
    def corr(self) -> pd.DataFrame: ...

    @property
    def flags(self) -> Sequence[object]: ...

    @property
    def notes(self) -> tuple[str, ...]: ...

    def conf_int(self, alpha: float = 0.05) -> pd.DataFrame: ...


def parameter_lines(fit: ShownFit) -> list[str]:
    """The parameter lines of the summary: value, σ (Eq. 3), relative σ, the 95 %
    t-interval and the unit."""
    lines = [
        f"{'param':>8} {'value':>14} {'stderr (Eq.3)':>14} {'rel.':>8} {'95% CI (t)':>25}  unit"
    ]
    ci = fit.conf_int(0.05)
    for name, v, s in zip(fit.param_names, fit.values, fit.stderr_values, strict=True):
        rel = abs(s / v) if v != 0 else np.inf
        lines.append(
            f"{name:>8} {v:>14.6g} {s:>14.4g} {rel:>8.2%} "
            f"[{ci.loc[name, 'lower']:>11.5g},{ci.loc[name, 'upper']:>11.5g}]  "  # type: ignore[str-bytes-safe]  # pandas-stubs: .loc[row, col] is any scalar
            f"{fit.units.get(name, '')}"
        )
    return lines


def fit_summary(fit: ShownFit, parameters: list[str]) -> str:
    """A fit report in the manner of lmfit and statsmodels, ending with numbered notes;
    ``parameters``: its parameter lines (:func:`parameter_lines`, or a subclass's own)."""
    width = 78
    lines = [
        f" {fit.model_name} fit ".center(width, "="),
        f"{'Method:':<18}{fit.method}",
        f"{'Converged:':<18}{fit.converged} ({fit.message})",
        f"{'Observations:':<18}{fit.nobs:<12d}{'Parameters:':<14}{len(fit.params):<6d}"
        f"{'DoF:':<6}{fit.dof}",
        f"{'Function evals:':<18}{fit.nfev:<12d}{'Iterations:':<14}{fit.niter}",
        f"{'epsilon (Eq. 2):':<18}{fit.epsilon:<12.4f}{'Weighted RSS:':<14}{fit.rss:.6g}",
        f"{'Reduced chi^2:':<18}{fit.redchi:<12.4g}{'AIC:':<14}{fit.aic:<12.6g}"
        f"{'BIC:':<6}{fit.bic:.6g}",
        f"{'Jacobian:':<18}{fit.jacobian_method:<12}{'cond(J):':<14}{fit.condition_number:.3g}",
        "-" * width,
        *parameters,
    ]
    if len(fit.params) > 1:
        lines.append("-" * width)
        lines.append("Correlations:")
        names = fit.param_names
        for i in range(len(names)):
            for j in range(i + 1, len(names)):
                lines.append(f"  corr({names[i]}, {names[j]}) = {fit.corr.iloc[i, j]:+.4f}")  # type: ignore[str-bytes-safe]  # pandas-stubs: .iloc[i, j] is any scalar
    lines.append("-" * width)
    flags = fit.flags
    lines.append("Health: OK" if not flags else f"Health: {len(flags)} flag(s)")
    lines.extend(f"  ! {flag}" for flag in flags)
    notes = (
        "Cov = s^2 (J^T J)^-1 with s^2 = sum (w e)^2 / (N - Np) (Eq. 4), J = d(w f)/dtheta "
        "(Eq. 5); stderr = sqrt(diag Cov) (Eq. 3).",
        "epsilon (Eq. 2) = 1 - sqrt(sum (w e)^2 / (N - 2)) / (sum |w y| / N), on the "
        "weighted data as in the paper's normalised pressures.",
        *fit.notes,
    )
    lines.extend(notes_block(notes))
    lines.append("=" * width)
    return "\n".join(lines)


def parameter_frame(fit: ShownFit) -> pd.DataFrame:
    """Value, σ (Eq. 3), the 95 % interval and the unit of every parameter."""
    ci = fit.conf_int(0.05)
    return pd.DataFrame(
        {
            "param": list(fit.param_names),
            "value": [f"{v:.6g}" for v in fit.values],
            "stderr (Eq. 3)": [f"{s:.4g}" for s in fit.stderr_values],
            "95% CI (t)": [
                f"[{ci.loc[n, 'lower']:.5g}, {ci.loc[n, 'upper']:.5g}]" for n in fit.param_names  # type: ignore[str-bytes-safe]  # pandas-stubs: .loc[row, col] is any scalar
            ],
            "unit": [fit.units.get(n, "") for n in fit.param_names],
        }
    )


def fit_html(fit: ShownFit, parameters: pd.DataFrame) -> str:
    """The summary as tables, for notebooks; ``parameters``: the parameter table
    (:func:`parameter_frame`, or a subclass's own)."""
    facts = {
        "method": fit.method,
        "converged": f"{fit.converged} ({fit.message})",
        "observations": fit.nobs,
        "epsilon (Eq. 2)": f"{fit.epsilon:.4f}",
        "reduced chi-square": f"{fit.redchi:.4g}",
        "AIC / BIC": f"{fit.aic:.4f} / {fit.bic:.4f}",
    }
    health = [str(f) for f in fit.flags] or ["OK"]
    return result_html(
        f"{fit.model_name} fit",
        facts_html(facts),
        table_html(parameters),
        _correlation_html(fit),
        notes_html(health, "Health"),
        notes_html(fit.notes),
    )


def _correlation_html(fit: ShownFit) -> str:
    """The correlations of the estimates as a table (empty for one parameter)."""
    if len(fit.param_names) < 2:
        return ""
    frame = fit.corr.map(lambda v: f"{v:+.3f}" if np.isfinite(v) else "–")
    return table_html(frame, index=True, caption="Correlations")
