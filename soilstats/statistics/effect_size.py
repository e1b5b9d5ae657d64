"""Effect sizes of ANOVA tables: η², partial η², ω² and partial ω².

For an effect with sum of squares SS, degrees of freedom df, residual mean square MS_e,
residual sum of squares SS_e, total (corrected) sum of squares SS_T and N observations:

* η² = SS / SS_T  (for a one-way table, the R² of the model)
* partial η² = SS / (SS + SS_e)
* ω² = (SS − df·MS_e) / (SS_T + MS_e)  (less biased than η²; may be negative — no effect)
* partial ω² = (SS − df·MS_e) / (SS + (N − df)·MS_e)

For one-way tables η² = partial η² and ω² = partial ω².  SS_T is taken from
``table.attrs["ss_total"]`` when present (two-way tables of unbalanced data, whose type II sums
do not add up to SS_T), otherwise it is the sum of the table's sums of squares.
"""

from __future__ import annotations

import pandas as pd

from ._data import StatisticsInputError

__all__ = ["effect_sizes"]

_RESIDUAL_ROWS = ("within", "Residual")


def effect_sizes(table: pd.DataFrame) -> pd.DataFrame:
    """Effect sizes for every effect row of an ANOVA table.

    Parameters
    ----------
    table : pandas.DataFrame
        A table from :func:`anova_oneway` (rows ``between``/``within``), :func:`anova_twoway`
        or :func:`statsmodels.stats.anova.anova_lm` (last row ``Residual``): columns ``df``
        and ``sum_sq``.

    Returns
    -------
    pandas.DataFrame
        One row per effect (the residual row excluded), columns ``eta_sq``,
        ``partial_eta_sq``, ``omega_sq``, ``partial_omega_sq`` (dimensionless).

    Raises
    ------
    StatisticsInputError
        No ``df``/``sum_sq`` columns or no residual row.
    """
    for col in ("df", "sum_sq"):
        if col not in table.columns:
            raise StatisticsInputError(
                f"not in the ANOVA table (columns {list(table.columns)}); pass a table from "
                "anova_oneway, anova_twoway or statsmodels' anova_lm",
                column=col,
            )
    resid = [r for r in _RESIDUAL_ROWS if r in table.index]
    if not resid:
        raise StatisticsInputError(
            f"the ANOVA table has no residual row (looked for {list(_RESIDUAL_ROWS)}, "
            f"found {list(table.index)})"
        )
    ss_e = float(table.loc[resid[0], "sum_sq"])  # type: ignore[arg-type]  # pandas-stubs: .loc[row, col] is any scalar
    df_e = float(table.loc[resid[0], "df"])  # type: ignore[arg-type]  # pandas-stubs: .loc[row, col] is any scalar
    ms_e = ss_e / df_e
    effects = table.drop(index=resid[0])
    ss_t = float(table.attrs.get("ss_total", table["sum_sq"].sum()))
    n_obs = float(table.attrs.get("n_obs", table["df"].sum() + 1))
    ss, df = effects["sum_sq"].astype(float), effects["df"].astype(float)
    out = pd.DataFrame(
        {
            "eta_sq": ss / ss_t,
            "partial_eta_sq": ss / (ss + ss_e),
            "omega_sq": (ss - df * ms_e) / (ss_t + ms_e),
            "partial_omega_sq": (ss - df * ms_e) / (ss + (n_obs - df) * ms_e),
        },
        index=effects.index,
    )
    return out
