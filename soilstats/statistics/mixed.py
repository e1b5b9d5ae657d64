"""ANOVA of a factor when one blocking factor is a random sample (operators): the factor is
tested against the factor × random-block mean square.

A preparation study (the paper's Section 3.1.1, Table 1 criterion 2: "several persons")
crosses the methods with a few operators.  The operators are a *sample* of the people who
might prepare a soil bin, and each may prepare each method a little differently — a bias that
is persistent for one person and one method (the method × operator interaction, γ_ij).  The
model is then

    y_ijk = μ + α_i + β_block + o_j + γ_ij + ε_ijk,   o_j ~ N(0, σ_o²), γ_ij ~ N(0, σ_γ²),

and a claim about the *methods* (α) must hold for other people too.  A test of α against the
residual mean square treats the tests as independent replicates; the γ_ij of the few
operators then do not average out, and with σ_γ > 0 that test rejects a true null far more
often than α (31 % at α = 0.05 on the bundled preparation design with the simulator's
``operator_cv`` of methods 9 and 10).  The classical mixed-model test (Scheffé 1959 §8;
Montgomery, *Design and Analysis of Experiments*, §13.3) uses as denominator the mean square
whose expectation holds the same σ_γ² term as the factor's:

    F = MS_factor / MS_factor×random   on (df_factor, df_factor×random).

For a balanced design (equal counts in every cell) this F has exactly the F distribution
under the null, whatever σ_o and σ_γ, as long as every factor level has the same σ_γ and
test-to-test scatter; for unbalanced data it is an approximation (the expected mean squares
then weigh σ_γ² slightly differently), stated in ``attrs["balanced"]``.  Where the levels
scatter unequally (preparation methods: stiffness cv 0.08–0.32) use
:func:`soilstats.statistics.welch_random_block`, which gives each level its own variance.
This F is preferred over a REML fit (``statsmodels`` ``MixedLM``) because it is exact for the
designs studies use, needs no iteration that can fail to converge with three operators, and
costs one least-squares fit per term.

Sums of squares are type II, as :func:`anova_twoway`: each term after every term that does
not contain it (the factor and the random block after the other main effects, the
interaction after all main effects, a fixed block after everything else).  They are formed
from nested least-squares fits with ranks taken from the design, so empty cells lower the
degrees of freedom instead of breaking the fit.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import stats

from ._data import StatisticsInputError, prepare
from .twoway import check_estimable, dummy_design

__all__ = ["anova_random_block"]

COLUMNS = ["df", "sum_sq", "mean_sq", "F", "PR(>F)", "error_term"]


def _rss(x: np.ndarray, y: np.ndarray) -> tuple[float, int]:
    """Residual sum of squares and rank of the least-squares fit of ``y`` on ``x``."""
    beta, _, rank, _ = np.linalg.lstsq(x, y, rcond=None)
    r = y - x @ beta
    return float(r @ r), int(rank)


def _cells(frame: pd.DataFrame, a: str, b: str) -> np.ndarray:
    """Indicator columns of every (a, b) cell that holds an observation."""
    codes, _ = pd.factorize(frame[a].astype(str) + "\x1f" + frame[b].astype(str))
    return np.eye(codes.max() + 1)[codes]


def random_block_input(
    data: pd.DataFrame,
    response: str,
    factor: str,
    blocks: str | Sequence[str],
    random: str,
    *,
    dropna: bool,
) -> tuple[list[str], pd.DataFrame, int]:
    """(blocks as a list, the prepared frame, rows dropped) for a test of ``factor`` with
    ``random`` one of ``blocks``: the input checks both random-block tests share (this
    module's and :func:`.hetero.welch_random_block`)."""
    blocks = [blocks] if isinstance(blocks, str) else list(blocks)
    if random not in blocks:
        raise StatisticsInputError(
            f"the random block must be one of the blocks {blocks}", column=random
        )
    frame, n_dropped = prepare(data, [response], [factor, *blocks], dropna=dropna)
    check_estimable(frame, factor, blocks)
    return blocks, frame, n_dropped


def _f_tests(table: pd.DataFrame, error: dict[str, str]) -> pd.DataFrame:
    """``table`` (rows of ``sum_sq``, ``df``, ``mean_sq``) with each term's F against the
    mean square of its ``error`` row, its p-value and its ``error_term``, in the columns
    :data:`COLUMNS`."""
    table["F"] = np.nan
    table["PR(>F)"] = np.nan
    for term, err in error.items():
        if not table.loc[err, "mean_sq"] > 0:  # type: ignore[arg-type, operator]  # pandas-stubs: .loc[row, col] is any scalar
            continue  # exact data: no scatter to test against (F and p stay NaN)
        f = table.loc[term, "mean_sq"] / table.loc[err, "mean_sq"]  # type: ignore[operator]  # pandas-stubs: as above
        table.loc[term, "F"] = f  # type: ignore[assignment, index]  # pandas-stubs: as above
        table.loc[term, "PR(>F)"] = stats.f.sf(f, table.loc[term, "df"], table.loc[err, "df"])  # type: ignore[arg-type, index]  # pandas-stubs: as above
    table["error_term"] = pd.Series(error, dtype=object).reindex(table.index).fillna("")
    return table[COLUMNS]


def anova_random_block(
    data: pd.DataFrame,
    response: str,
    factor: str,
    blocks: str | Sequence[str],
    random: str,
    *,
    dropna: bool = False,
) -> pd.DataFrame:
    """Type II ANOVA of ``factor`` with ``random`` (one of ``blocks``) a random sample.

    Parameters
    ----------
    data : pandas.DataFrame
        Tidy data, one row per observation (one test).  Not modified.
    response : str
        Numeric response column (e.g. ``log10_p_ref``, log10 of a pressure in Pa).
    factor : str
        The setup factor under study (fixed: e.g. the preparation method).
    blocks : str or sequence of str
        Blocking factors, including ``random`` (e.g. ``["b_m", "operator"]``).
    random : str
        The block whose levels are a random sample (e.g. ``"operator"``).
    dropna : bool, default False
        Drop rows with missing values (counted in ``attrs["n_dropped"]``) instead of raising.

    Returns
    -------
    pandas.DataFrame
        Rows ``factor``, each block, ``"factor:random"``, ``"Residual"``; columns ``df,
        sum_sq, mean_sq`` (response unit²), ``F``, ``PR(>F)`` and ``error_term``, the row
        whose mean square is the F's denominator: ``"factor:random"`` for the factor and the
        random block (the unrestricted mixed model), ``"Residual"`` for the interaction and
        the fixed blocks.  ``attrs`` as :func:`anova_twoway` (``balanced`` counts the
        factor × random cells) plus ``random``, ``error_term`` (of the factor) and
        ``df_error``.

    Raises
    ------
    ConfoundingError
        The factor cannot be separated from the blocks.
    StatisticsInputError
        Bad input as :func:`anova_twoway`; ``random`` not among ``blocks``; no factor ×
        random interaction degrees of freedom (e.g. a factor level seen by one operator
        only); or no replicate within the factor × random cells (the residual of the
        additive model is then the interaction: test with :func:`anova_twoway`).
    """
    blocks, frame, n_dropped = random_block_input(
        data, response, factor, blocks, random, dropna=dropna
    )
    y = frame[response].to_numpy(dtype=np.float64)
    y = y - np.median(y)  # changes no sum of squares, keeps the fits well scaled
    inter = f"{factor}:{random}"
    cells = _cells(frame, factor, random)

    def design(main: list[str], with_cells: bool) -> np.ndarray:
        x = dummy_design(frame, main)
        return np.hstack([x, cells]) if with_cells else x

    main = [factor, *blocks]
    rss_main, rank_main = _rss(design(main, False), y)
    rss_full, rank_full = _rss(design(main, True), y)
    df_int = rank_full - rank_main
    df_res = len(y) - rank_full
    if df_int < 1:
        raise StatisticsInputError(
            f"no {factor} × {random} interaction can be estimated (each {random} would have to "
            f"test two or more {factor} levels that another {random} tested too); counts:\n"
            f"{pd.crosstab(frame[factor], frame[random]).to_string()}",
            column=random,
        )
    if df_res < 1:
        raise StatisticsInputError(
            f"no replicate within the {factor} × {random} cells: the residual of the additive "
            f"model is the {factor} × {random} interaction itself (test with anova_twoway)",
            column=response,
        )
    rows = {}
    for term in main:  # main effects after the other main effects ...
        if term in (factor, random):
            rss, rank = _rss(design([t for t in main if t != term], False), y)
            rows[term] = (rss - rss_main, rank_main - rank)
        else:  # ... a fixed block after everything without it, the interaction included
            rss, rank = _rss(design([t for t in main if t != term], True), y)
            rows[term] = (rss - rss_full, rank_full - rank)
    rows[inter] = (rss_main - rss_full, df_int)
    rows["Residual"] = (rss_full, df_res)
    table = pd.DataFrame(rows, index=["sum_sq", "df"]).T
    table["sum_sq"] = table["sum_sq"].clip(lower=0.0)
    table["mean_sq"] = table["sum_sq"] / table["df"]
    error = {t: (inter if t in (factor, random) else "Residual") for t in [*main, inter]}
    table = _f_tests(table, error)
    counts = frame.groupby([factor, random], sort=False).size().to_numpy()
    n_cells = frame[factor].nunique() * frame[random].nunique()
    centred = y - y.mean()
    table.attrs.update(
        test=f"type II ANOVA, {factor} against {factor} × {random} ({random} random)",
        typ=2,
        response=response,
        factor=factor,
        blocks=blocks,
        random=random,
        error_term=inter,
        df_error=int(df_int),
        n_obs=len(y),
        n_dropped=n_dropped,
        ss_total=float(centred @ centred),
        balanced=bool(counts.size == n_cells and (counts == counts[0]).all()),
    )
    return table
