"""One-way analysis of variance, accurate to the last digits the data hold.

The table is the textbook one (sums of squares between and within the levels of one factor,
F = MS_between / MS_within on (k − 1, N − k) degrees of freedom), but the sums are formed so
that rounding does not eat the answer when the responses share many leading digits, as the
NIST StRD sets SmLs01–09 do on purpose:

1. the response is centred on a robust shift, the lower median (an observation, so the
   subtraction y − shift is exact for all values within a factor two of it);
2. group and grand means take two passes (mean, then the mean of the residuals as correction);
3. every sum is compensated (:func:`math.fsum`).

The result is then the exact ANOVA of the float64 values received, to about 13 digits.  What
remains is the representation of the input: a value such as 1000000000000.4 cannot be held
in float64 (its spacing there is 2⁻¹³ ≈ 1.2·10⁻⁴), so on SmLs07–09 the data themselves carry
only 3–4 significant digits of their deviations, and no algorithm working on float64 input
can give more.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy import stats

from ._data import StatisticsInputError, prepare

__all__ = ["anova_oneway"]

COLUMNS = ["df", "sum_sq", "mean_sq", "F", "PR(>F)"]


def _mean(x: np.ndarray) -> float:
    """Two-pass compensated mean: the first-pass mean corrected by the mean residual."""
    m = math.fsum(x) / x.size
    return m + math.fsum(x - m) / x.size


def anova_oneway(
    data: pd.DataFrame, response: str, factor: str, *, dropna: bool = False
) -> pd.DataFrame:
    """One-way ANOVA table of ``response`` by the levels of ``factor``.

    Parameters
    ----------
    data : pandas.DataFrame
        Tidy data, one row per observation (e.g. one identified parameter per test).  Not
        modified.
    response : str
        Column of the numeric response (any unit; the sums of squares are in its unit squared).
    factor : str
        Column whose distinct values are the groups (e.g. ``"preparation"``).
    dropna : bool, default False
        Rows with a missing response or factor raise unless this is True; then they are
        dropped and counted in ``attrs["n_dropped"]``.

    Returns
    -------
    pandas.DataFrame
        Index ``["between", "within"]``, columns ``df, sum_sq, mean_sq, F, PR(>F)`` (the
        names :func:`statsmodels.stats.anova.anova_lm` uses); ``F`` and ``PR(>F)`` are NaN on
        the ``within`` row.  ``attrs`` holds ``response``, ``factor``, ``n_obs``,
        ``n_levels``, ``levels`` (in order of first appearance), ``n_dropped``, ``shift``
        (the value subtracted before summing) and ``test`` (``"one-way ANOVA"``).

    Raises
    ------
    StatisticsInputError
        A column is missing, the response is not finite, fewer than two levels, a declared
        (categorical) level without observations, no replicate at all (N = k, so no
        within-group degrees of freedom), or missing values without ``dropna=True``.

    Notes
    -----
    With every group free of scatter (SS_within = 0) F is ``inf`` (or NaN when the group
    means are also equal) and the p-value 0 (or NaN).  The numerics are described in the
    module docstring; they reproduce all eleven NIST StRD one-way ANOVA sets.

    Examples
    --------
    >>> import pandas as pd
    >>> d = pd.DataFrame({"method": list("aabbcc"), "n": [1.0, 1.2, 1.5, 1.7, 0.9, 1.1]})
    >>> table = anova_oneway(d, "n", "method")
    >>> float(table.loc["between", "df"]), round(float(table.loc["between", "F"]), 2)
    (2.0, 10.33)
    """
    frame, n_dropped = prepare(data, [response], [factor], dropna=dropna)
    y = frame[response].to_numpy(dtype=np.float64)
    codes, levels = pd.factorize(frame[factor])
    n, k = y.size, len(levels)
    if n <= k:
        raise StatisticsInputError(
            f"each of the {k} levels has a single observation ({n} rows), so there is no "
            "within-group scatter to test against; the one-way ANOVA needs replicates",
            column=factor,
        )
    shift = float(np.partition(y, (n - 1) // 2)[(n - 1) // 2])
    d = y - shift
    grand = _mean(d)
    ss_within_terms = []
    ss_between_terms = []
    for j in range(k):
        g = d[codes == j]
        m = _mean(g)
        ss_within_terms.append((g - m) ** 2)
        ss_between_terms.append(g.size * (m - grand) ** 2)
    ss_within = math.fsum(np.concatenate(ss_within_terms))
    ss_between = math.fsum(ss_between_terms)
    df_between, df_within = float(k - 1), float(n - k)
    ms_between, ms_within = ss_between / df_between, ss_within / df_within
    if ms_within > 0:
        f = ms_between / ms_within
        p = float(stats.f.sf(f, df_between, df_within))
    elif ms_between > 0:
        f, p = math.inf, 0.0
    else:
        f, p = math.nan, math.nan
    table = pd.DataFrame(
        [
            [df_between, ss_between, ms_between, f, p],
            [df_within, ss_within, ms_within, math.nan, math.nan],
        ],
        index=pd.Index(["between", "within"]),
        columns=COLUMNS,
    )
    table.attrs.update(
        test="one-way ANOVA",
        response=response,
        factor=factor,
        n_obs=n,
        n_levels=k,
        levels=list(levels),
        n_dropped=n_dropped,
        shift=shift,
    )
    return table
