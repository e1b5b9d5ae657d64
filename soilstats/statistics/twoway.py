"""ANOVA of one setup factor with other setup variables as blocking factors (type II).

A study asks whether *one* factor (say the plate velocity) changes a response, while other
setup variables vary too (the test day, the operator).  Those enter the model as blocks:

    y = μ + α_factor + β_block (+ (αβ) if ``interaction``) + ε

and the factor is tested by its **type II** sum of squares: the reduction in residual sum of
squares when the factor is added to a model that already holds every other term not containing
it.  Why type II: it tests the factor after the blocks whatever the order they are written in
(type I depends on order), and respects marginality — a main effect is never tested "in the
presence of" its own interaction, which is what type III does and which is rarely a meaningful
hypothesis (it also depends on the contrast coding).  With balanced data types I, II and III
coincide.  Tables come from :func:`statsmodels.stats.anova.anova_lm` with ``typ=2``.

If the blocks absorb some of the factor's degrees of freedom (each method tested on its own
day, say), the factor's effect cannot be told apart from the blocks' and a
:class:`ConfoundingError` says so, rather than returning an F with the wrong degrees of freedom.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
import statsmodels.formula.api as smf
from statsmodels.stats.anova import anova_lm

from ._data import ConfoundingError, StatisticsInputError, prepare

__all__ = ["anova_twoway", "dummy_design"]

COLUMNS = ["df", "sum_sq", "mean_sq", "F", "PR(>F)"]


def dummy_design(frame: pd.DataFrame, columns: Sequence[str]) -> np.ndarray:
    """Intercept plus treatment-coded dummies of ``columns`` (for rank checks and cross-checks)."""
    parts = [np.ones((len(frame), 1))]
    for col in columns:
        codes, _ = pd.factorize(frame[col])
        parts.append(np.eye(codes.max() + 1)[codes][:, 1:])
    return np.hstack(parts)


def check_estimable(frame: pd.DataFrame, factor: str, blocks: list[str]) -> None:
    rank = np.linalg.matrix_rank
    x_blocks = dummy_design(frame, blocks)
    x_full = dummy_design(frame, [*blocks, factor])
    if rank(x_blocks) < x_blocks.shape[1]:
        raise StatisticsInputError(
            f"the blocking factors {blocks} are confounded with each other (their design has "
            f"rank {rank(x_blocks)} < {x_blocks.shape[1]} columns); keep only one of them"
        )
    k = frame[factor].nunique()
    lost = x_full.shape[1] - rank(x_full)
    if lost:
        pattern = pd.crosstab(frame[factor], [frame[b] for b in blocks])
        raise ConfoundingError(
            f"the levels of {factor!r} are confounded with the block(s) {blocks}: {lost} of its "
            f"{k - 1} degrees of freedom cannot be separated from the blocks (e.g. a level seen "
            f"in one block only). Observations per cell:\n{pattern.to_string()}\n"
            f"Test {factor!r} alone with anova_oneway and report that its effect includes the "
            f"effect of {blocks}.",
            factor=factor,
            block=", ".join(blocks),
            df_lost=lost,
        )


def anova_twoway(
    data: pd.DataFrame,
    response: str,
    factor: str,
    block: str | Sequence[str],
    *,
    interaction: bool = False,
    dropna: bool = False,
) -> pd.DataFrame:
    """Type II ANOVA table of ``response`` by ``factor`` with blocking factor(s).

    Parameters
    ----------
    data : pandas.DataFrame
        Tidy data, one row per observation.  Not modified.
    response : str
        Numeric response column.
    factor : str
        The setup factor under study.
    block : str or sequence of str
        Blocking factor(s) (e.g. ``"session"`` or ``["session", "operator"]``).
    interaction : bool, default False
        Add the factor × block interaction (one block only; needs replicates in every cell).
    dropna : bool, default False
        Drop rows with missing values (counted in ``attrs["n_dropped"]``) instead of raising.

    Returns
    -------
    pandas.DataFrame
        Rows: ``factor``, each block, ``"factor:block"`` if ``interaction``, ``"Residual"``;
        columns ``df, sum_sq, mean_sq, F, PR(>F)``.  ``attrs``: ``test``, ``typ`` (2),
        ``response``, ``factor``, ``blocks``, ``n_obs``, ``n_dropped``, ``ss_total``,
        ``balanced`` (equal counts in every factor × block cell).

    Raises
    ------
    ConfoundingError
        The factor cannot be separated from the blocks.
    StatisticsInputError
        Missing columns or values, non-finite response, fewer than two levels, empty cells with
        ``interaction``, or no residual degrees of freedom.
    """
    blocks = [block] if isinstance(block, str) else list(block)
    if not blocks:
        raise StatisticsInputError("block is empty; use anova_oneway for a single factor")
    if interaction and len(blocks) != 1:
        raise StatisticsInputError(
            f"interaction=True needs exactly one block, got {blocks}; pass a single block"
        )
    frame, n_dropped = prepare(data, [response], [factor, *blocks], dropna=dropna)
    check_estimable(frame, factor, blocks)
    # Safe internal names (column names may hold spaces or operators); response centred on its
    # median, which changes no sum of squares but keeps the normal equations well scaled.
    names = {factor: "f", **{b: f"b{i}" for i, b in enumerate(blocks)}}
    work = pd.DataFrame({new: frame[old].astype(str) for old, new in names.items()})
    y = frame[response].to_numpy(dtype=np.float64)
    work["y"] = y - np.median(y)
    terms = [f"C({names[c]})" for c in [factor, *blocks]]
    if interaction:
        terms.append(f"C(f):C({names[blocks[0]]})")
        cells = pd.crosstab(frame[factor], frame[blocks[0]])
        if (cells.to_numpy() == 0).any():
            raise StatisticsInputError(
                f"the {factor} × {blocks[0]} interaction needs an observation in every cell; "
                f"counts:\n{cells.to_string()}\nfit without interaction",
                column=factor,
            )
    model = smf.ols("y ~ " + " + ".join(terms), data=work).fit()
    if model.df_resid < 1:
        raise StatisticsInputError(
            f"no residual degrees of freedom ({len(work)} rows for {int(model.df_model) + 1} "
            "parameters); the design needs replicates",
            column=response,
        )
    table = anova_lm(model, typ=2)
    rename = {f"C({v})": k for k, v in names.items()}
    if interaction:
        rename[f"C(f):C({names[blocks[0]]})"] = f"{factor}:{blocks[0]}"
    table = table.rename(index=rename)
    table["mean_sq"] = table["sum_sq"] / table["df"]
    table = table[COLUMNS].astype(float)
    counts = frame.groupby([factor, *blocks], sort=False).size().to_numpy()
    n_cells = frame[factor].nunique() * np.prod([frame[b].nunique() for b in blocks])
    centred = work["y"].to_numpy() - work["y"].mean()
    table.attrs.update(
        test="two-way ANOVA (type II sums of squares)",
        typ=2,
        response=response,
        factor=factor,
        blocks=blocks,
        n_obs=len(work),
        n_dropped=n_dropped,
        ss_total=float(np.dot(centred, centred)),
        balanced=bool(counts.size == n_cells and (counts == counts[0]).all()),
    )
    return table
