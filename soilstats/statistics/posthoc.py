"""Tukey's HSD: which pairs of levels differ, with family-wise error held at α.

After an ANOVA says "the levels differ", the study wants to know *which* (e.g. which plate
shapes soften the soil).  Tukey's honestly significant difference compares every pair with the
studentized range distribution, so the simultaneous confidence intervals cover all pairwise
differences with probability 1 − α.  Computation by
:func:`statsmodels.stats.multicomp.pairwise_tukeyhsd` (Tukey–Kramer for unequal group sizes).
"""

from __future__ import annotations

import pandas as pd
from statsmodels.stats.multicomp import pairwise_tukeyhsd

from ._data import StatisticsInputError, prepare

__all__ = ["tukey_hsd"]


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
    if not 0.0 < alpha < 1.0:
        raise StatisticsInputError(f"alpha must lie in (0, 1), got {alpha!r}; e.g. alpha=0.05")
    frame, n_dropped = prepare(data, [response], [factor], dropna=dropna)
    labels = frame[factor].astype(str)
    if labels.nunique() != frame[factor].nunique():
        raise StatisticsInputError(
            "two levels print the same as strings (e.g. 1 and '1'); make the labels distinct",
            column=factor,
        )
    if len(frame) <= labels.nunique():
        raise StatisticsInputError(
            "every level has a single observation; Tukey's HSD needs replicates", column=factor
        )
    y = frame[response].to_numpy(dtype=float)
    res = pairwise_tukeyhsd(y - y.mean(), labels.to_numpy(), alpha=alpha)
    out = pd.DataFrame(
        {
            "group1": res.group_c,
            "group2": res.group_t,
            "meandiff": res.meandiffs,
            "p_adj": res.pvalues,
            "lower": res.confint[:, 0],
            "upper": res.confint[:, 1],
            "reject": res.reject.astype(bool),
        }
    )
    out.attrs.update(
        test="Tukey HSD",
        alpha=alpha,
        response=response,
        factor=factor,
        n_obs=len(frame),
        n_dropped=n_dropped,
    )
    return out
