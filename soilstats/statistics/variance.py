"""Between-repetition scatter: per-level spread, tests of equal variances, Welch's ANOVA.

The paper's criterion 2 asks for a *bounded between-repetition scatter*: a preparation method
is better when repeated tests agree.  :func:`scatter_table` gives the spread per level;
:func:`variance_test` tests whether the spreads differ — by default the Brown–Forsythe test
(Levene's test on absolute deviations from the group *median*, robust to the skewed,
outlier-prone scatter of a handful of soil tests); ``center="mean"`` gives Levene's original.
Both are the one-way ANOVA F of the absolute deviations |y − centre_g|.
:func:`welch_anova` compares the *means* without assuming equal variances.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import pandas as pd
from scipy import stats
from statsmodels.stats.oneway import anova_oneway as _sm_anova_oneway

from ._data import StatisticsInputError, prepare
from .result import TestResult

__all__ = ["scatter_table", "variance_test", "welch_anova"]


def _groups(frame: pd.DataFrame, response: str, factor: str, need: int) -> dict:
    groups = {
        lvl: g[response].to_numpy(dtype=float) for lvl, g in frame.groupby(factor, sort=False)
    }
    small = {lvl: g.size for lvl, g in groups.items() if g.size < need}
    if small:
        raise StatisticsInputError(
            f"every level needs at least {need} observations to estimate its scatter; "
            f"too few in {small}",
            column=factor,
        )
    return groups


def scatter_table(
    data: pd.DataFrame, response: str, factor: str, *, dropna: bool = False
) -> pd.DataFrame:
    """Spread of ``response`` within each level of ``factor``.

    Returns
    -------
    pandas.DataFrame
        Indexed by level (order of first appearance), columns ``n, mean, sd`` (ddof 1, the
        response's unit; NaN for a single observation), ``cv`` (sd / |mean|), ``min, max``.
        ``attrs["n_dropped"]`` counts rows dropped with ``dropna=True``.
    """
    frame, n_dropped = prepare(data, [response], [factor], dropna=dropna, min_levels={factor: 1})
    g = frame.groupby(factor, sort=False)[response]
    out = pd.DataFrame({"n": g.size(), "mean": g.mean(), "sd": g.std(ddof=1)})
    out["cv"] = out["sd"] / out["mean"].abs()
    out["min"], out["max"] = g.min(), g.max()
    out.attrs.update(response=response, factor=factor, n_dropped=n_dropped)
    return out


def variance_test(
    data: pd.DataFrame,
    response: str,
    factor: str,
    *,
    center: Literal["median", "mean"] = "median",
    dropna: bool = False,
) -> TestResult:
    """Test whether the scatter of ``response`` differs between the levels of ``factor``.

    Parameters
    ----------
    center : {"median", "mean"}, default "median"
        ``"median"``: Brown–Forsythe test (robust; recommended); ``"mean"``: Levene's test.

    Returns
    -------
    TestResult
        F statistic on (k − 1, N − k) degrees of freedom; effect size η² of the ANOVA of the
        absolute deviations (share of their variation explained by the level).

    Raises
    ------
    StatisticsInputError
        Bad input as for :func:`anova_oneway`, a level with fewer than 2 observations, or an
        unknown ``center``.
    """
    if center not in ("median", "mean"):
        raise StatisticsInputError(f"center must be 'median' or 'mean', got {center!r}")
    frame, n_dropped = prepare(data, [response], [factor], dropna=dropna)
    groups = list(_groups(frame, response, factor, need=2).values())
    stat, p = stats.levene(*groups, center=center)
    k, n = len(groups), sum(g.size for g in groups)
    ctr = np.median if center == "median" else np.mean
    z = [np.abs(g - ctr(g)) for g in groups]
    zall = np.concatenate(z)
    ss_b = sum(zi.size * (zi.mean() - zall.mean()) ** 2 for zi in z)
    ss_t = float(np.sum((zall - zall.mean()) ** 2))
    name = "Brown–Forsythe (Levene, median)" if center == "median" else "Levene (mean)"
    notes = [f"H0: equal variances of {response!r} in all {k} levels of {factor!r}"]
    if n_dropped:
        notes.append(f"{n_dropped} row(s) with missing values dropped")
    return TestResult(
        test=name,
        statistic=float(stat),
        p_value=float(p),
        df_num=float(k - 1),
        df_den=float(n - k),
        effect_size=float(ss_b / ss_t) if ss_t > 0 else float("nan"),
        effect_size_name="eta_sq",
        notes=tuple(notes),
    )


def welch_anova(
    data: pd.DataFrame, response: str, factor: str, *, dropna: bool = False
) -> TestResult:
    """Welch's one-way ANOVA: equal means, without assuming equal variances.

    Returns
    -------
    TestResult
        Welch's F on (k − 1, ν) degrees of freedom, ν fractional; no effect size.

    Raises
    ------
    StatisticsInputError
        Bad input as for :func:`anova_oneway`, a level with fewer than 2 observations, or a
        level without scatter (Welch weights each level by n / s², undefined for s = 0).
    """
    frame, n_dropped = prepare(data, [response], [factor], dropna=dropna)
    groups = _groups(frame, response, factor, need=2)
    flat = [lvl for lvl, g in groups.items() if np.ptp(g) == 0]
    if flat:
        raise StatisticsInputError(
            f"level(s) {flat} have no scatter (all values equal); Welch's test weights levels "
            "by n/s² and is undefined — use anova_oneway instead",
            column=factor,
        )
    y = frame[response].to_numpy(dtype=float)
    res = _sm_anova_oneway(
        y - np.median(y), frame[factor].astype(str).to_numpy(), use_var="unequal"
    )
    notes = [f"H0: equal means of {response!r} in all {len(groups)} levels of {factor!r}"]
    if n_dropped:
        notes.append(f"{n_dropped} row(s) with missing values dropped")
    return TestResult(
        test="Welch ANOVA (unequal variances)",
        statistic=float(res.statistic),
        p_value=float(res.pvalue),
        df_num=float(res.df[0]),
        df_den=float(res.df[1]),
        notes=tuple(notes),
    )
