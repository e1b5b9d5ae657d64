"""ANCOVA for shear: do the Mohr–Coulomb lines τ = c + σ·tanφ differ between groups?

With shear stress τ as response, normal stress σ as covariate and a setup variable as group
(ring size, grouser height, …), three nested least-squares models are compared:

* M0 ``τ ~ σ``           one line for all groups (common c and φ);
* M1 ``τ ~ σ + group``   parallel lines: own intercept c_g, common slope tanφ;
* M2 ``τ ~ σ * group``   separate lines: own c_g and tanφ_g.

Two F-tests answer the paper's question:

* **slopes** (do the friction angles differ?): M1 against M2;
* **intercepts** (do the cohesions differ, given a common slope?): M0 against M1.

Both use the residual mean square of the largest model M2 as denominator, the convention of
:func:`statsmodels.stats.anova.anova_lm` (and R's ``anova``) for a sequence of models, so each
test stays valid when the other hypothesis is false.  F = (RSS_small − RSS_big)/Δdf ÷
RSS_M2/df_M2.  When the slopes differ, the intercept test compares the groups at the data's
average σ rather than at σ = 0; read it together with the per-group lines.

``variance="fitted"`` (what the shear studies use) does not assume one residual variance.
Shear tests scatter more at high σ — each preparation draws its own φ, so sd(τ) grows with
σ (a review: residual sd 17 → 137 Pa from 3 to 20 kPa) — and under ordinary least squares
the slope and line tests then rejected a true null at ~0.11 for α = 0.05, while the
cohesion test (an extrapolation to σ = 0) almost never did.  The variance is modelled as
v(σ) = a + b·σ² (constant scatter of c, plus scatter of tanφ), fitted to the squared,
leverage-corrected residuals of M2 by non-negative least squares, and all three models are
fitted by weighted least squares with weights 1/v (feasible GLS).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
import statsmodels.api as sm
from scipy.optimize import nnls
from statsmodels.stats.anova import anova_lm

from ..errors import InputError
from ..outputs import json_safe
from ._data import StatisticsInputError, prepare
from .result import TestResult

__all__ = ["AncovaResult", "ancova", "fitted_variance_weights"]


@dataclass(frozen=True)
class AncovaResult:
    """Comparison of the common, parallel and separate lines of ``response`` on ``covariate``.

    Attributes
    ----------
    comparison : pandas.DataFrame
        Rows ``common``, ``parallel``, ``separate`` (M0, M1, M2); columns ``df_resid, ssr,
        df_diff, ss_diff, F, PR(>F)`` as :func:`statsmodels.stats.anova.anova_lm` computes
        them (its ``Pr(>F)`` renamed ``PR(>F)`` like the other tables here).
    lines : pandas.DataFrame
        Per group (from M2): ``n``, ``intercept`` (c, the response's unit), ``intercept_stderr``,
        ``slope`` (tanφ when response and covariate share a unit), ``slope_stderr``, ``phi_deg``
        (atan(slope) in degrees).  Standard errors use M2's pooled residual variance.
    response, covariate, group : str
        The columns analysed.
    n_obs, n_dropped : int
        Observations used and rows dropped for missing values.
    separate_fit : statsmodels RegressionResults
        The fit of M2 (own intercepts, then own slopes, in the order of ``lines``), weighted
        by 1/v(σ) with ``variance="fitted"``; :attr:`separate_intercepts_test` reads it.
    """

    comparison: pd.DataFrame
    lines: pd.DataFrame
    response: str
    covariate: str
    group: str
    n_obs: int
    n_dropped: int
    #: The statsmodels fit with a slope per group (untyped: statsmodels has no stubs).
    separate_fit: Any = field(default=None, repr=False, compare=False)

    def _test(self, row: str, what: str) -> TestResult:
        r = self.comparison.loc[row]
        ssr_full = self.comparison.loc["separate", "ssr"]
        notes = [f"H0: {what}; denominator: residual mean square of the separate-lines model"]
        if self.n_dropped:
            notes.append(f"{self.n_dropped} row(s) with missing values dropped")
        return TestResult(
            test=f"ANCOVA F-test of H0: {what}",
            statistic=float(r["F"]),  # type: ignore[arg-type]  # pandas-stubs: .loc[row] may be a frame (the rows are unique)
            p_value=float(r["PR(>F)"]),  # type: ignore[arg-type]  # pandas-stubs: .loc[row] may be a frame (the rows are unique)
            df_num=float(r["df_diff"]),  # type: ignore[arg-type]  # pandas-stubs: .loc[row] may be a frame (the rows are unique)
            df_den=float(self.comparison.loc["separate", "df_resid"]),  # type: ignore[arg-type]  # pandas-stubs: .loc[row, col] is any scalar
            effect_size=float(r["ss_diff"] / (r["ss_diff"] + ssr_full)),  # type: ignore[operator, arg-type, type-var]  # pandas-stubs: .loc[row] may be a frame, .loc[row, col] any scalar
            effect_size_name="partial_eta_sq",
            notes=tuple(notes),
        )

    @property
    def slope_test(self) -> TestResult:
        """Do the slopes (friction angles φ) differ between groups?  (parallel vs separate)"""
        return self._test("separate", f"one slope of {self.response!r} on {self.covariate!r}")

    @property
    def intercept_test(self) -> TestResult:
        """Do the intercepts (cohesions c) differ, given a common slope?  (common vs parallel)"""
        return self._test("parallel", "one intercept, given a common slope")

    @property
    def separate_intercepts_test(self) -> TestResult:
        """Do the intercepts (cohesions c) differ when each group keeps its own slope?  A
        Wald F-test on M2 (:attr:`intercept_test` assumes a common slope, and where the
        slopes differ it compares the lines at the mean σ, which is not c)."""
        k = len(self.lines)
        contrasts = np.zeros((k - 1, 2 * k))
        contrasts[:, 0] = 1.0
        contrasts[np.arange(k - 1), np.arange(1, k)] = -1.0
        wald = self.separate_fit.f_test(contrasts)
        f = float(np.squeeze(wald.fvalue))
        return TestResult(
            test="Wald F-test of H0: equal intercepts c in the separate-lines model",
            statistic=f,
            p_value=float(wald.pvalue),
            df_num=float(wald.df_num),
            df_den=float(wald.df_denom),
            effect_size=f * wald.df_num / (f * wald.df_num + wald.df_denom),
            effect_size_name="partial_eta_sq",
        )

    def summary(self) -> str:
        """Model comparison, per-group lines and both tests, with numbered notes."""
        with pd.option_context("display.width", 120, "display.precision", 4):
            parts = [
                f"ANCOVA of {self.response!r} on {self.covariate!r} by {self.group!r} "
                f"({self.n_obs} observations)",
                "",
                self.comparison.to_string(),
                "",
                self.lines.to_string(),
                "",
                self.slope_test.summary(),
                "",
                self.intercept_test.summary(),
            ]
        return "\n".join(parts)

    def to_dict(self) -> dict:
        """The JSON-ready content: the model comparison, the lines per group, both tests."""
        return json_safe(
            {
                "response": self.response,
                "covariate": self.covariate,
                "group": self.group,
                "n_obs": self.n_obs,
                "n_dropped": self.n_dropped,
                "comparison": self.comparison.reset_index(names="model").to_dict("records"),
                "lines": self.lines.reset_index().to_dict("records"),
                "slope_test": self.slope_test.to_dict(),
                "intercept_test": self.intercept_test.to_dict(),
            }
        )

    def __str__(self) -> str:
        return self.summary()


def ancova(
    data: pd.DataFrame,
    response: str,
    covariate: str,
    group: str,
    *,
    dropna: bool = False,
    variance: str = "constant",
) -> AncovaResult:
    """Compare the straight lines of ``response`` against ``covariate`` between groups.

    Parameters
    ----------
    data : pandas.DataFrame
        Tidy data, one row per (σ, τ) point.  Not modified.
    response : str
        Shear stress column τ (e.g. kPa).
    covariate : str
        Normal stress column σ (same unit as τ for the slope to be tanφ).
    group : str
        Setup variable whose levels are compared.
    dropna : bool, default False
        Drop rows with missing values (counted in ``n_dropped``) instead of raising.
    variance : {"constant", "fitted"}
        ``constant``: ordinary least squares (one residual variance); ``fitted``: weighted
        least squares with v(σ) = a + b·σ² fitted to the residuals (module docstring).

    Returns
    -------
    AncovaResult
        With ``slope_test`` and ``intercept_test`` (see the module docstring for the models).

    Raises
    ------
    StatisticsInputError
        Bad input as for :func:`anova_oneway`, a group with fewer than two distinct covariate
        values (no slope), or no residual degrees of freedom for the separate-lines model.
    """
    frame, n_dropped = prepare(data, [response, covariate], [group], dropna=dropna)
    distinct = frame.groupby(group, sort=False)[covariate].nunique()
    flat = distinct[distinct < 2]
    if len(flat):
        raise StatisticsInputError(
            f"group(s) {list(flat.index)} have fewer than two distinct {covariate!r} values, so "
            "their slope is undefined; every group needs tests at two or more normal stresses",
            column=group,
        )
    k, n = len(distinct), len(frame)
    if n <= 2 * k:
        raise StatisticsInputError(
            f"{n} points cannot test {k} separate lines ({2 * k} parameters); the "
            "separate-lines model needs residual degrees of freedom",
            column=response,
        )
    y = frame[response].to_numpy(dtype=float)
    x = frame[covariate].to_numpy(dtype=float)
    codes, levels = pd.factorize(frame[group])
    onehot = np.eye(k)[codes]
    # The three nested designs, built directly (no formula parsing: fast in simulation loops).
    designs = [
        np.column_stack([np.ones(n), x]),  # M0: τ ~ σ
        np.column_stack([onehot, x]),  # M1: τ ~ σ + group
        np.hstack([onehot, onehot * x[:, None]]),  # M2: τ ~ σ * group (separate lines)
    ]
    if variance not in ("constant", "fitted"):
        raise InputError(f"variance must be 'constant' or 'fitted', got {variance!r}")
    weights = fitted_variance_weights(y, x, designs[2]) if variance == "fitted" else None
    if weights is None:
        fits = [sm.OLS(y, design).fit() for design in designs]
    else:
        fits = [sm.WLS(y, design, weights=weights).fit() for design in designs]
    comparison = anova_lm(*fits).rename(columns={"Pr(>F)": "PR(>F)"})  # as in the other tables
    comparison.index = pd.Index(["common", "parallel", "separate"])
    sep = fits[2]
    lines = pd.DataFrame(
        {
            "n": np.bincount(codes, minlength=k),
            "intercept": sep.params[:k],
            "intercept_stderr": sep.bse[:k],
            "slope": sep.params[k:],
            "slope_stderr": sep.bse[k:],
        },
        index=pd.Index(list(levels), name=group),
    )
    lines["phi_deg"] = [math.degrees(math.atan(s)) for s in lines["slope"]]
    return AncovaResult(
        comparison=comparison,
        lines=lines,
        response=response,
        covariate=covariate,
        group=group,
        n_obs=n,
        n_dropped=n_dropped,
        separate_fit=sep,
    )


def fitted_variance_weights(y: np.ndarray, x: np.ndarray, design: np.ndarray) -> np.ndarray | None:
    """Weights 1/v(x) with v(x) = a + b·x² (a, b ≥ 0) fitted to the squared residuals of the
    OLS fit of ``y`` on ``design``, each divided by 1 − its leverage (so E r² = v); None when
    the fit leaves no positive variance (then ordinary least squares is all one can do)."""
    fit = sm.OLS(y, design).fit()
    leverage = fit.get_influence().hat_matrix_diag
    r2 = fit.resid**2 / np.clip(1.0 - leverage, 1e-6, None)
    basis = np.column_stack([np.ones_like(x), (x / np.max(np.abs(x))) ** 2])
    coef, _ = nnls(basis, r2)
    v = basis @ coef
    if not np.all(v > 0):
        return None
    return 1.0 / v
