"""Tukey's HSD: which pairs of levels differ, with family-wise error held at α.

After an ANOVA says "the levels differ", the study wants to know *which* (e.g. which plate
shapes soften the soil).  Tukey's honestly significant difference compares every pair with the
studentized range distribution, so the simultaneous confidence intervals cover all pairwise
differences with probability 1 − α.  Computation by
:func:`statsmodels.stats.multicomp.pairwise_tukeyhsd` (Tukey–Kramer for unequal group sizes).

With blocking factors (operator, plate size), :func:`tukey_lsmeans` compares the
least-squares (estimated marginal) means of the blocked model instead of raw means: removing
raw block means from the response, as soilstats did until November 2026, biases the pairwise
differences whenever the levels are spread unevenly over the blocks (a level tested mostly by
a "stiff" operator inherits that operator's bias) and its intervals ignore the block degrees
of freedom.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy.stats import studentized_range
from statsmodels.stats.multicomp import pairwise_tukeyhsd

from ._data import StatisticsInputError, prepare

__all__ = ["tukey_hsd", "tukey_lsmeans"]


def _pair_data(
    data: pd.DataFrame, response: str, factor: str, blocks: list, alpha: float, dropna: bool
) -> tuple[pd.DataFrame, int, pd.Series]:
    """The checked rows of a pairwise comparison, how many were dropped, and the factor's
    levels as text (which must stay distinct)."""
    if not 0.0 < alpha < 1.0:
        raise StatisticsInputError(f"alpha must lie in (0, 1), got {alpha!r}; e.g. alpha=0.05")
    frame, n_dropped = prepare(data, [response], [factor, *blocks], dropna=dropna)
    labels = frame[factor].astype(str)
    if labels.nunique() != frame[factor].nunique():
        raise StatisticsInputError(
            "two levels print the same as strings (e.g. 1 and '1'); make the labels distinct",
            column=factor,
        )
    return frame, n_dropped, labels


def tukey_hsd(
    data: pd.DataFrame,
    response: str,
    factor: str,
    *,
    alpha: float = 0.05,
    dropna: bool = False,
) -> pd.DataFrame:
    """All pairwise comparisons of the levels of ``factor`` by Tukey's HSD.

    Parameters
    ----------
    data : pandas.DataFrame
        Tidy data, one row per observation.  Not modified.
    response, factor : str
        Numeric response column and grouping column.
    alpha : float, default 0.05
        Family-wise error rate; the intervals are simultaneous (1 − α) intervals.
    dropna : bool, default False
        Drop rows with missing values (counted in ``attrs["n_dropped"]``) instead of raising.

    Returns
    -------
    pandas.DataFrame
        One row per pair, columns ``group1, group2, meandiff`` (mean of group2 − mean of
        group1, in the response's unit), ``p_adj`` (adjusted for all pairs), ``lower, upper``
        (simultaneous interval of ``meandiff``), ``reject`` (True where ``p_adj < alpha``).
        Levels are compared as strings, in sorted order.  ``attrs``: ``alpha``, ``response``,
        ``factor``, ``n_obs``, ``n_dropped``, ``test``.

    Raises
    ------
    StatisticsInputError
        Bad input as for :func:`anova_oneway`, ``alpha`` outside (0, 1), or no replicate.
    """
    frame, n_dropped, labels = _pair_data(data, response, factor, [], alpha, dropna)
    if len(frame) <= labels.nunique():
        raise StatisticsInputError(
            "every level has a single observation; Tukey's HSD needs replicates", column=factor
        )
    y = frame[response].to_numpy(dtype=float)
    res = pairwise_tukeyhsd(y - y.mean(), labels.to_numpy(), alpha=alpha)
    return _pairs_frame(
        res.group_c,
        res.group_t,
        res.meandiffs,
        res.pvalues,
        res.confint,
        res.reject.astype(bool),
        test="Tukey HSD",
        alpha=alpha,
        response=response,
        factor=factor,
        n_obs=len(frame),
        n_dropped=n_dropped,
    )


@functools.lru_cache(maxsize=256)
def _q_crit(alpha: float, k: int, df: float) -> float:
    """Critical studentized range q(1 − α; k, df): kept, since scipy's ppf integrates
    numerically (~0.1 s) and studies ask again for the same (α, k, df) — per soil, per
    response, and when a default is re-evaluated (:mod:`soilstats.study.defaults`)."""
    return float(studentized_range.ppf(1 - alpha, k, df))


def tukey_lsmeans(
    data: pd.DataFrame,
    response: str,
    factor: str,
    blocks: str | Sequence[str] = (),
    *,
    alpha: float = 0.05,
    error: tuple[float, float] | None = None,
    dropna: bool = False,
    p_values: bool = True,
) -> pd.DataFrame:
    """Tukey–Kramer pairs of the least-squares means of ``factor`` in the additive block model.

    The model is ``y = μ + α_level + Σ β_block + ε`` (least squares).  The least-squares
    (estimated marginal) mean of a level is its prediction averaged over the block levels
    with equal weights; the difference of two of them is the difference of their α, whatever
    the weights, so it is free of the block effects however unevenly the levels are spread
    over the blocks.  Its standard error comes from the model's covariance ``σ̂²·(XᵀX)⁻¹``,
    and the simultaneous intervals and adjusted p-values from the studentized range with
    k levels and the error degrees of freedom (Tukey–Kramer; conservative for unbalanced
    designs, Hayter 1984).  Without blocks this is :func:`tukey_hsd` exactly.

    Parameters
    ----------
    data, response, factor, alpha, dropna
        As :func:`tukey_hsd`.
    blocks : str or sequence of str, optional
        Blocking factors of the model (additive, fixed).
    error : (mean square, degrees of freedom), optional
        Error term instead of the model's residual: e.g. the factor × operator mean square
        and its df when operators are random (:func:`anova_random_block`), so that the pairs
        face the same error as the factor's F-test.
    p_values : bool, default True
        Compute the adjusted p-values (``p_adj``; NaN when False).  Each one integrates the
        studentized range numerically (~25 ms a pair); the intervals and ``reject`` do not
        need them (a study re-evaluating a default reads only those).

    Returns
    -------
    pandas.DataFrame
        As :func:`tukey_hsd`: ``group1, group2, meandiff`` (LS mean of group2 − LS mean of
        group1, response unit), ``p_adj``, ``lower, upper``, ``reject``, plus ``std_err`` of
        the difference.  ``attrs``: ``test``, ``alpha``, ``response``, ``factor``, ``blocks``,
        ``df_error``, ``n_obs``, ``n_dropped``.

    Raises
    ------
    StatisticsInputError
        Bad input as :func:`tukey_hsd`, a level confounded with the blocks, or no error
        degrees of freedom.
    """
    blocks = [blocks] if isinstance(blocks, str) else list(blocks)
    frame, n_dropped, labels = _pair_data(data, response, factor, blocks, alpha, dropna)
    levels = np.unique(labels.to_numpy())
    k = len(levels)
    codes = np.searchsorted(levels, labels.to_numpy())
    parts = [np.ones((len(frame), 1)), np.eye(k)[codes][:, 1:]]
    for block in blocks:
        b_codes, _ = pd.factorize(frame[block].astype(str), sort=True)
        parts.append(np.eye(b_codes.max() + 1)[b_codes][:, 1:])
    x = np.hstack(parts)
    if np.linalg.matrix_rank(x) < x.shape[1]:
        raise StatisticsInputError(
            f"the levels of {factor!r} cannot be separated from the blocks {blocks} (rank-"
            "deficient design); compare the levels without blocks and state the confounding",
            column=factor,
        )
    y = frame[response].to_numpy(dtype=float)
    y = y - y.mean()
    xtx_inv = np.linalg.inv(x.T @ x)
    beta = xtx_inv @ (x.T @ y)
    if error is None:
        df = len(y) - x.shape[1]
        if df < 1:
            raise StatisticsInputError(
                "no residual degrees of freedom; Tukey pairs need replicates", column=factor
            )
        resid = y - x @ beta
        ms = float(resid @ resid) / df
    else:
        ms, df = float(error[0]), float(error[1])
        if not (ms >= 0 and df >= 1):
            raise StatisticsInputError(f"error term {error!r} needs a mean square ≥ 0 and df ≥ 1")
    if not ms > 0:
        raise StatisticsInputError(
            "the error mean square is 0 (exact data): no scatter to judge the pairs by",
            column=factor,
        )
    # level effects relative to the first level (0 for it), and their covariance
    eff = np.concatenate([[0.0], beta[1:k]])
    cov = np.zeros((k, k))
    cov[1:, 1:] = ms * xtx_inv[1:k, 1:k]
    i1, i2 = np.triu_indices(k, 1)
    diff = eff[i2] - eff[i1]
    se = np.sqrt(cov[i1, i1] + cov[i2, i2] - 2 * cov[i1, i2])
    q_crit = _q_crit(alpha, k, df)
    q = np.abs(diff) / se * np.sqrt(2.0)
    p_adj = np.atleast_1d(studentized_range.sf(q, k, df) if p_values else np.full(q.shape, np.nan))
    half = q_crit / np.sqrt(2.0) * se
    return _pairs_frame(
        levels[i1],
        levels[i2],
        diff,
        np.clip(p_adj, 0.0, 1.0),
        np.column_stack([diff - half, diff + half]),
        q > q_crit,
        std_err=se,
        test="Tukey–Kramer on least-squares means"
        + (f" (blocks {', '.join(blocks)})" if blocks else ""),
        alpha=alpha,
        response=response,
        factor=factor,
        blocks=blocks,
        df_error=df,
        n_obs=len(frame),
        n_dropped=n_dropped,
    )


def _pairs_frame(group1, group2, meandiff, p_adj, interval, reject, *, std_err=None, **attrs):
    """The pairs table both Tukey functions return: ``group1, group2, meandiff, p_adj, lower,
    upper, reject`` (and ``std_err`` when given), ``attrs`` as given."""
    columns = {
        "group1": group1,
        "group2": group2,
        "meandiff": meandiff,
        "p_adj": p_adj,
        "lower": interval[:, 0],
        "upper": interval[:, 1],
        "reject": reject,
    }
    if std_err is not None:
        columns["std_err"] = std_err
    out = pd.DataFrame(columns)
    out.attrs.update(attrs)
    return out
