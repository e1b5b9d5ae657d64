"""Verdicts across soils and responses, with multiple-comparison control.

A study tests one factor on many (soil, response) pairs — e.g. velocity on k_c, k_φ and n of
three soils, nine tests.  At α = 0.05 each, the chance of at least one false "effect" is far
above 5 %.  :func:`verdicts` adjusts the p-values of one family of tests (by default all rows
given; Holm's step-down method, which controls the family-wise error rate at α under any
dependence and is uniformly more powerful than Bonferroni) and declares an effect significant
when its *adjusted* p-value is below α.  Adjustment by
:func:`statsmodels.stats.multitest.multipletests`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np
import pandas as pd
from statsmodels.stats.multitest import multipletests

from ._data import StatisticsInputError
from .effect_size import effect_sizes
from .result import TestResult

__all__ = ["VERDICT_COLUMNS", "adjust_p_values", "effect_row", "verdicts"]

VERDICT_COLUMNS = [
    "soil",
    "response",
    "factor",
    "statistic",
    "p_value",
    "p_adjusted",
    "significant",
    "effect_size",
    "test",
]
_INPUT = ["soil", "response", "factor", "statistic", "p_value", "effect_size", "test"]
_METHODS = (
    "holm",
    "bonferroni",
    "sidak",
    "holm-sidak",
    "simes-hochberg",
    "hommel",
    "fdr_bh",
    "fdr_by",
)


def adjust_p_values(p: np.ndarray, alpha: float = 0.05, method: str = "holm") -> np.ndarray:
    """Adjusted p-values of one family of tests (the one place soilstats adjusts them).

    Parameters
    ----------
    p : array of float
        The raw p-values of the family, in any order.
    alpha : float
        The family-wise level (used by the step methods of ``multipletests``).
    method : str
        Any method of :func:`statsmodels.stats.multitest.multipletests`; Holm by default.

    Holm is written out (sorted p_(i) times m − i + 1, running maximum, capped at 1 — the
    formula of statsmodels' ``multipletests``, checked against it in the tests) because
    ``multipletests(method="holm")`` calls ``gc.collect()`` on every call, ~0.1 s in a
    process holding pandas and statsmodels; the other methods are delegated to it.
    """
    if method != "holm":
        return multipletests(p, alpha=alpha, method=method)[1]
    order = np.argsort(p, kind="stable")
    steps = np.arange(p.size, 0, -1)
    out = np.empty_like(p)
    out[order] = np.minimum(1.0, np.maximum.accumulate(p[order] * steps))
    return out


def effect_row(soil: str, response: str, factor: str, result: TestResult | pd.DataFrame) -> dict:
    """One input row for :func:`verdicts` from a :class:`TestResult` or an ANOVA table.

    For an ANOVA table (from :func:`anova_oneway` or :func:`anova_twoway`) the factor's row is
    used (``between`` for one-way) and the effect size is its partial η² (= η² for one-way),
    against the row's ``error_term`` where the table names one (:func:`anova_random_block`).
    """
    if isinstance(result, TestResult):
        stat, p, es, test = result.statistic, result.p_value, result.effect_size, result.test
    elif isinstance(result, pd.DataFrame):
        row = "between" if "between" in result.index else factor
        if row not in result.index:
            raise StatisticsInputError(
                f"the ANOVA table has no row {factor!r} (rows {list(result.index)})", column=factor
            )
        stat, p = float(result.loc[row, "F"]), float(result.loc[row, "PR(>F)"])  # type: ignore[arg-type]  # pandas-stubs: .loc[row, col] is any scalar
        error = str(result.loc[row, "error_term"]) if "error_term" in result.columns else ""
        if error and error in result.index:
            # A factor tested against another term (a random block's interaction): its
            # partial η² is taken against that same term, as its F is.
            ss = float(result.loc[row, "sum_sq"])  # type: ignore[arg-type]  # pandas-stubs: .loc[row, col] is any scalar
            es = ss / (ss + float(result.loc[error, "sum_sq"]))  # type: ignore[arg-type]  # pandas-stubs: .loc[row, col] is any scalar
        else:
            es = float(effect_sizes(result).loc[row, "partial_eta_sq"])  # type: ignore[arg-type]  # pandas-stubs: .loc[row, col] is any scalar
        test = result.attrs.get("test", "ANOVA")
    else:
        raise StatisticsInputError(
            f"result must be a TestResult or an ANOVA DataFrame, got {type(result).__name__}"
        )
    return dict(
        soil=soil,
        response=response,
        factor=factor,
        statistic=stat,
        p_value=p,
        effect_size=es,
        test=test,
    )


def verdicts(
    effects: pd.DataFrame | Iterable[Mapping],
    *,
    alpha: float = 0.05,
    method: str = "holm",
    family: str | Sequence[str] | None = None,
) -> pd.DataFrame:
    """Adjust p-values for multiple comparisons and state a verdict per test.

    Parameters
    ----------
    effects : pandas.DataFrame or iterable of mappings
        One row per test with ``soil, response, factor, statistic, p_value, effect_size,
        test`` (see :func:`effect_row`); extra columns are kept, after the standard ones.
    alpha : float, default 0.05
        Family-wise error rate (or false discovery rate for the ``fdr_*`` methods).
    method : str, default "holm"
        Any method of :func:`statsmodels.stats.multitest.multipletests`: ``holm``,
        ``bonferroni``, ``sidak``, ``holm-sidak``, ``simes-hochberg``, ``hommel``, ``fdr_bh``,
        ``fdr_by``.
    family : str or sequence of str, optional
        Column(s) defining separate families (e.g. ``"soil"`` to control the error rate per
        soil).  Default: all rows form one family — the conservative choice.

    Returns
    -------
    pandas.DataFrame
        Columns ``soil, response, factor, statistic, p_value, p_adjusted, significant,
        effect_size, test`` (then any extra input columns), the input's row order.
        ``attrs``: ``alpha``, ``method``, ``family``, ``n_tests``.

    Raises
    ------
    StatisticsInputError
        Missing columns, p-values outside [0, 1] or missing (drop untestable rows and report
        them separately), ``alpha`` outside (0, 1), or an unknown ``method``.
    """
    if not 0.0 < alpha < 1.0:
        raise StatisticsInputError(f"alpha must lie in (0, 1), got {alpha!r}; e.g. alpha=0.05")
    if method not in _METHODS:
        raise StatisticsInputError(f"unknown method {method!r}; choose one of {list(_METHODS)}")
    frame = effects.copy() if isinstance(effects, pd.DataFrame) else pd.DataFrame(list(effects))
    for col in _INPUT:
        if col not in frame.columns:
            raise StatisticsInputError(
                f"not in the effects (columns {list(frame.columns)}); build rows with effect_row",
                column=col,
            )
    p = pd.to_numeric(frame["p_value"], errors="coerce").to_numpy(dtype=float)
    bad = ~((p >= 0) & (p <= 1))
    if bad.any():
        rows = frame.loc[bad, ["soil", "response", "factor"]].to_dict("records")
        raise StatisticsInputError(
            f"{int(bad.sum())} p-value(s) missing or outside [0, 1], e.g. {rows[:3]}; drop "
            "tests that could not be run and report them separately",
            column="p_value",
        )
    fam = [] if family is None else [family] if isinstance(family, str) else list(family)
    for col in fam:
        if col not in frame.columns:
            raise StatisticsInputError("family column not in the effects", column=col)
    adjusted = np.empty_like(p)
    keys = frame.groupby(fam, sort=False).indices.values() if fam else [np.arange(len(p))]
    for idx in keys:
        if len(idx):
            adjusted[idx] = adjust_p_values(p[idx], alpha, method)
    frame["p_value"] = p
    frame["p_adjusted"] = adjusted
    frame["significant"] = adjusted < alpha
    extra = [c for c in frame.columns if c not in VERDICT_COLUMNS]
    out = frame[VERDICT_COLUMNS + extra].reset_index(drop=True)
    out.attrs.update(alpha=alpha, method=method, family=fam or None, n_tests=len(out))
    return out
