"""The factor's test with a random block when the factor's levels scatter unequally.

:func:`soilstats.statistics.anova_random_block` tests a preparation method against the
method × operator mean square.  That mean square pools all methods: it assumes that every
method's operator cell means scatter alike.  They do not — a shovel method (Table 2, methods
9 and 10) scatters several times more than the garden rake (13), and its persons' biases are
larger too.  The few methods with large scatter then carry most of the pooled F's numerator
and denominator, so the F has far fewer effective degrees of freedom than (k − 1,
(k − 1)(o − 1)) and rejects a true null too often (0.17 instead of 0.05 on the bundled design).

:func:`welch_random_block` gives every level its own variance:

1. **Cell means.**  The least-squares fit of the response on the factor × random cells and the
   fixed blocks (plate size) gives one adjusted mean Y_ij per level i and random level j
   (operator), and per level the test-to-test variance s²_i (residuals of level i over their
   share of the residual degrees of freedom, Σ (1 − h_kk)).
2. **One variance per level** of its cell means, v_i = σ²_γ,i + σ²_ε,i / n_cell: Shukla's
   (1972) unbiased estimator from the double-centred table (the operators' main effects
   cancel), bounded below by s²_i × the mean of the cells' (XᵀX)⁻¹ diagonal — the part of v_i
   that the many within-cell degrees of freedom pin down.
3. **Welch-type statistic** on the level means m_i = mean_j Y_ij (variance v_i / o):
   T = Σ w_i (m_i − m_w)², w_i = o / v_i, m_w the w-weighted mean; a constant added to every
   m_i (an operator's main effect) leaves T unchanged.  Reported as A = T / (k − 1), which is
   ≈ F(k − 1, ∞) when the v_i are known.
4. **Parametric bootstrap null** (Krishnamoorthy, Lu & Mathew, *Comput. Stat. Data Anal.*
   51, 2007): tables Y* ~ N(0, v_i) and s²*_i ~ s²_i χ²_df / df are drawn, and steps 2–3
   are repeated on each.  With three operators each v_i rests on two degrees of freedom; the
   bootstrap carries that noise into the null distribution, where Welch's χ² approximation
   (df o − 1 per variance) gave a test that never rejected (0.000 on the null, 400 campaigns).

Measured on the bundled preparation design (docs/studies.md): any significant method verdict
in 0.030 of 400 null campaigns (0.142 with the pooled F), and a × 1.26 pressure of method 13
found after Holm in 0.87 of 150 campaigns on soil01 (0.32): the precise methods are no longer
compared against the shovel methods' scatter.  Alone it is liberal where the levels in fact
scatter alike (0.08–0.11 at α = 0.05 for 3–13 methods), so the preparation study declares an
effect only when the pooled F rejects too (:func:`soilstats.study.effects.factor_effects`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from ._data import StatisticsInputError
from .mixed import random_block_input
from .result import TestResult

__all__ = ["shukla_variances", "welch_random_block"]


def shukla_variances(cell_means: np.ndarray) -> np.ndarray:
    """Shukla's (1972) unbiased variance of each row of a two-way table without replicates.

    Model Y_ij = μ_i + o_j + e_ij with independent e_ij of variance v_i (one per row i): the
    column effects o_j (operators) cancel in the double-centred residuals w_ij, whose row sums
    of squares S_i have E[S_i] = (o − 1)[(1 − 2/k) v_i + Σ v / k²]; solved for v_i.

    Parameters
    ----------
    cell_means : numpy.ndarray
        Shape (..., k, o): k ≥ 3 rows (factor levels), o ≥ 2 columns (random levels), in the
        response's unit; leading axes are independent tables.

    Returns
    -------
    numpy.ndarray
        Shape (..., k): v_i in the response's unit², unbiased, hence negative at times.
    """
    y = np.asarray(cell_means, dtype=np.float64)
    k, o = y.shape[-2:]
    if k < 3 or o < 2:
        raise StatisticsInputError(
            f"one variance per level needs three or more levels and two random levels, got "
            f"{k} × {o}"
        )
    w = y - y.mean(-1, keepdims=True) - y.mean(-2, keepdims=True) + y.mean((-2, -1), keepdims=True)
    s = (w**2).sum(-1)
    total = k * s.sum(-1, keepdims=True) / ((o - 1) * (k - 1))
    return (s / (o - 1) - total / k**2) / (1 - 2 / k)


def _level_variances(y: np.ndarray, floor: np.ndarray) -> np.ndarray:
    return np.maximum(shukla_variances(y), floor)


def _welch_t(y: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """T = Σ w_i (m_i − m_w)² of each table (leading axes), w_i = o / v_i."""
    o = y.shape[-1]
    w = o / _level_variances(y, floor)
    m = y.mean(-1)
    mw = (w * m).sum(-1, keepdims=True) / w.sum(-1, keepdims=True)
    return (w * (m - mw) ** 2).sum(-1)


def _cell_fit(
    frame: pd.DataFrame, response: str, factor: str, fixed: list[str], random: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, pd.Index]:
    """Adjusted cell means (k × o), per-level s², its df and mean cell-mean variance factor."""
    levels = pd.Index(pd.unique(frame[factor]))
    randoms = pd.Index(pd.unique(frame[random]))
    counts = pd.crosstab(frame[factor], frame[random]).reindex(index=levels, columns=randoms)
    if (counts.fillna(0) == 0).any(axis=None):
        raise StatisticsInputError(
            f"one variance per {factor} needs every {factor} × {random} cell filled; "
            f"counts:\n{counts.fillna(0).astype(int).to_string()}",
            column=random,
        )
    cell = levels.get_indexer(frame[factor]) * len(randoms) + randoms.get_indexer(frame[random])  # type: ignore[arg-type]  # pandas-stubs: get_indexer takes an Index; a Series works the same
    parts = [np.eye(len(levels) * len(randoms))[cell]]
    for col in fixed:  # treatment-coded fixed blocks (plate size) beside the cell means
        codes, _ = pd.factorize(frame[col])
        parts.append(np.eye(codes.max() + 1)[codes][:, 1:])
    x = np.hstack(parts)
    y = frame[response].to_numpy(dtype=np.float64)
    y = y - np.median(y)  # keeps the fit well scaled; only differences of cell means matter
    q, r = np.linalg.qr(x)
    if np.linalg.matrix_rank(r) < x.shape[1]:
        raise StatisticsInputError(
            f"the {factor} × {random} cells are confounded with the fixed blocks {fixed}",
            column=factor,
        )
    beta = np.linalg.solve(r, q.T @ y)
    resid = y - x @ beta
    free = 1.0 - (q**2).sum(1)  # 1 − leverage: each test's share of the residual df
    r_inv = np.linalg.inv(r)
    c = (r_inv**2).sum(1)[: len(levels) * len(randoms)].reshape(len(levels), len(randoms))
    idx = levels.get_indexer(frame[factor])  # type: ignore[arg-type]  # pandas-stubs: get_indexer takes an Index; a Series works the same
    df = np.bincount(idx, weights=free, minlength=len(levels))
    ss = np.bincount(idx, weights=resid**2, minlength=len(levels))
    if (df < 1e-9).any():
        raise StatisticsInputError(
            f"no replicate within the {factor} × {random} cells: the test-to-test scatter of "
            f"each {factor} cannot be estimated",
            column=response,
        )
    means = beta[: len(levels) * len(randoms)].reshape(len(levels), len(randoms))
    return means, ss / df, df, c.mean(1), levels


def welch_random_block(
    data: pd.DataFrame,
    response: str,
    factor: str,
    blocks: str | Sequence[str],
    random: str,
    *,
    n_boot: int = 9999,
    seed: int = 0,
    dropna: bool = False,
) -> TestResult:
    """Test ``factor`` with ``random`` a random block and one variance per factor level.

    See the module docstring for the statistic and its parametric bootstrap null.

    Parameters
    ----------
    data : pandas.DataFrame
        Tidy data, one row per test.  Not modified.
    response : str
        Numeric response (e.g. ``log10_p_ref``, log10 of a pressure in Pa).
    factor : str
        The fixed factor under study (preparation method), three or more levels (with two,
        the random-block F of :func:`anova_random_block` is the paired t-test of the operator
        cell means, exact whatever the two variances).
    blocks : str or sequence of str
        Blocking factors including ``random``; the others (plate size) are fixed.
    random : str
        The random block (operator); every factor level must be seen by every one of its
        levels, each cell with a replicate.
    n_boot : int, default 9999
        Bootstrap tables; the p-value's Monte Carlo standard error is ≈ √(p(1 − p)/n_boot)
        (0.002 at p = 0.05).
    seed : int, default 0
        Seed of the bootstrap: the same data give the same p.
    dropna : bool, default False
        Drop rows with missing values instead of raising.

    Returns
    -------
    TestResult
        ``statistic`` A = T / (k − 1) (dimensionless), ``p_value`` = (1 + #{T* ≥ T}) /
        (n_boot + 1), ``df_num`` k − 1, ``df_den`` NaN (no F reference: the null is the
        bootstrap's); ``notes`` hold each level's v_i (response unit²) and how many were set
        by the within-cell bound.

    Raises
    ------
    StatisticsInputError
        Fewer than three levels or two random levels, an empty factor × random cell, no
        replicate within the cells, all scatter zero, or ``random`` not among ``blocks``.
    ConfoundingError
        The factor cannot be separated from the blocks.
    """
    blocks, frame, _ = random_block_input(data, response, factor, blocks, random, dropna=dropna)
    fixed = [b for b in blocks if b != random]
    means, s2, df, c, levels = _cell_fit(frame, response, factor, fixed, random)
    k, o = means.shape
    floor = s2 * c  # variance of a cell mean from the test-to-test scatter alone
    unbounded = shukla_variances(means)
    v = np.maximum(unbounded, floor)  # as _level_variances, keeping which bound won
    if not (v > 0).all():
        raise StatisticsInputError(
            f"no scatter of {response} within or between the cells of some {factor} levels: "
            "nothing to test against",
            column=response,
        )
    t = float(_welch_t(means, floor))
    rng = np.random.default_rng(seed)
    y_star = rng.standard_normal((n_boot, k, o)) * np.sqrt(v)[None, :, None]
    floor_star = floor[None, :] * rng.chisquare(df[None, :], (n_boot, k)) / df[None, :]
    t_star = _welch_t(y_star, floor_star)
    p = (1 + int((t_star >= t).sum())) / (n_boot + 1)
    bound = int((unbounded <= floor).sum())  # where the floor won (unit-free)
    return TestResult(
        test=(
            f"Welch-type test of {factor}, one variance per {factor}, {random} random "
            f"(parametric bootstrap, {n_boot} tables)"
        ),
        statistic=t / (k - 1),
        p_value=p,
        df_num=float(k - 1),
        df_den=float("nan"),
        notes=(
            "variance of the cell means per level: "
            + ", ".join(f"{lv}: {vi:.3g}" for lv, vi in zip(levels, v, strict=True)),
            f"{bound} of {k} variances set by the within-cell bound",
        ),
    )
