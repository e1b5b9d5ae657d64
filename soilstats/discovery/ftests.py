"""The F-tests of diagnosis: a candidate within strata, and an interaction of two.

A candidate X is tested on a per-test response y *within strata* of the other categorical
candidates: y = stratum + X + ε, the F-test of X after the strata, whose effects are absorbed
by centring within each stratum (Frisch–Waugh–Lovell) — only the strata in which X varies
carry information about it (:func:`strata_test`).  A categorical X enters as levels, a
continuous one as a linear trend (on ln x when x > 0 spans more than a factor four, except
a time/order candidate, whose drift is linear in time: :func:`trend_regressor`).  An
interaction A × B is the F-test of the A × B cells after A, B and the strata
(:func:`interaction_test`).  The tests work on integer level codes (:func:`strata_codes`,
:func:`cell_codes`), which keeps a campaign of thousands of tests fast.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

from .candidates import spans_log

#: A column counts towards a design's rank when its singular value exceeds this fraction of
#: the design's longest column as given: what the strata and other effects leave of a column
#: they carry entirely is rounding noise, ~1e-16 of its length.
_RANK_TOLERANCE = 1e-9

__all__ = [
    "cell_codes",
    "interaction_test",
    "strata_codes",
    "strata_test",
    "trend_regressor",
    "trend_slope",
]


def trend_regressor(x: np.ndarray, *, log_scale: bool = True) -> np.ndarray:
    """A continuous candidate as a regressor: ln x when x > 0 spans more than a factor four
    and ``log_scale`` allows it (not for time/order: a drift is linear in time or order —
    ln of a test number would make the first tests carry most of it)."""
    return np.log(x) if log_scale and spans_log(x) else x


def strata_codes(columns: list[np.ndarray], n: int) -> np.ndarray:
    """Stratum code of each of ``n`` rows: one per combination of the block codes given,
    numbered in the lexicographic order of the combinations."""
    if not columns:
        return np.zeros(n, int)
    columns = [np.asarray(c) for c in columns]
    radix = [int(c.max()) + 1 if c.size else 1 for c in columns]
    if all(c.dtype.kind in "iu" and (not c.size or c.min() >= 0) for c in columns) and (
        float(np.prod(radix, dtype=float)) < 2.0**62
    ):
        # Level codes: one mixed-radix integer per row orders as the rows do
        # lexicographically, so a 1-D unique numbers the strata exactly as the row-wise
        # unique below (which sorts rows of a structured view, far slower).
        combined = np.zeros(n, np.int64)
        for c, k in zip(columns, radix, strict=True):
            combined = combined * k + c
        return np.unique(combined, return_inverse=True)[1].ravel()
    return np.unique(np.column_stack(columns), axis=0, return_inverse=True)[1].ravel()


def _nested_f(y, design, strata, nuisance=None, cells=None) -> dict:
    """F-test of ``design`` after stratum effects (and ``nuisance`` columns), by
    within-stratum centring (Frisch–Waugh–Lovell).

    Returns ``statistic``, ``df1``, ``df2``, ``p_value``, ``effect_size`` (partial η²),
    ``sigma`` (residual standard deviation of the full model) and ``norm2`` (the squared
    length of each design column after the strata and nuisance are taken out: the pattern
    an effect of one unit leaves, for :mod:`.power`), or ``reason`` when it cannot be made.

    ``cells`` (optional codes) marks rows that share their stratum, design row and nuisance
    row.  Every column of every model is then constant within a cell, so the within-cell sum
    of squares W is left by all of them alike, and the rest is the regression of the cell
    means weighted by the cell counts m: rows scaled by √m, centred with m-weighted stratum
    means.  The same sums of squares, ranks (the scaled matrix has the same Gram matrix as
    the full one) and F, on a few hundred cells instead of thousands of tests.

    Ranks are judged against the columns as given, not as left: a column the strata and
    nuisance carry entirely (an interaction the main effects already hold) is left as
    rounding noise, ~1e-16 of its length, and must count for nothing.  Judged against the
    largest of what is left (noise itself, then), noise would count as rank and the test
    would be made on random directions: F(3, 24) with p anywhere in 0..1 for the
    interaction of a factor with a function of itself.
    """
    n = y.size
    s = pd.factorize(strata)[0]
    n_strata = s.max() + 1
    within, root = 0.0, None
    if cells is not None:
        codes = pd.factorize(cells)[0]
        m = np.bincount(codes).astype(float)
        if m.size < n:
            first = np.empty(m.size, int)
            first[codes] = np.arange(n)  # a row of each cell (all alike)
            mean = np.bincount(codes, weights=y) / m
            within = float(np.sum((y - mean[codes]) ** 2))
            y, design, s = mean, design[first], s[first]
            nuisance = None if nuisance is None else nuisance[first]
            root = np.sqrt(m)
    weight = np.ones(s.size) if root is None else root**2
    counts = np.bincount(s, weights=weight, minlength=n_strata)

    def centre(a):
        if root is None:
            sums = np.zeros((n_strata, *a.shape[1:]))
            np.add.at(sums, s, a)
            return a - (sums / counts.reshape(-1, *[1] * (a.ndim - 1)))[s]
        wa = a * weight.reshape(-1, *[1] * (a.ndim - 1))
        sums = np.zeros((n_strata, *a.shape[1:]))
        np.add.at(sums, s, wa)
        centred = a - (sums / counts.reshape(-1, *[1] * (a.ndim - 1)))[s]
        return centred * root.reshape(-1, *[1] * (a.ndim - 1))

    def length(a):
        """The longest column of ``a`` as the test sees it (rows weighted by the cells)."""
        rows = a if root is None else a * root.reshape(-1, *[1] * (a.ndim - 1))
        return float(np.sqrt(np.max(np.sum(rows**2, axis=0), initial=0.0)))

    def basis(a, scale):
        """Orthonormal basis of the columns of ``a``: the left singular vectors whose
        singular value exceeds 1e-9 × ``scale`` (the length of the columns before the strata
        and nuisance were taken out)."""
        if a.shape[1] == 0:
            return a[:, :0]
        u, sv, _ = np.linalg.svd(a, full_matrices=False)
        return u[:, sv > _RANK_TOLERANCE * scale]

    out = {"p_value": np.nan, "statistic": np.nan, "df1": 0, "df2": 0, "reason": ""}
    out.update(effect_size=np.nan, sigma=np.nan, norm2=np.full(design.shape[1], np.nan))
    yc, dc = centre(y), centre(design)
    r0 = 0
    if nuisance is not None and nuisance.shape[1]:
        q = basis(centre(nuisance), length(nuisance))
        r0 = q.shape[1]
        yc = yc - q @ (q.T @ yc)
        dc = dc - q @ (q.T @ dc)
    u = basis(dc, length(design))
    rank = u.shape[1]
    df2 = n - n_strata - r0 - rank
    if rank < 1:
        out["reason"] = (
            "nothing left to test: the strata and the other effects already carry every "
            "column of this design"
        )
        return out
    if df2 < 2:
        out["reason"] = f"no degrees of freedom left (n = {n}, strata = {n_strata}, rank = {rank})"
        return out
    left = yc - u @ (u.T @ yc)
    rss1 = within + float(left @ left)
    rss0 = within + float(yc @ yc)
    if rss1 <= 0:
        f_stat, p = (np.inf, 0.0) if rss0 > 0 else (np.nan, np.nan)
    else:
        f_stat = ((rss0 - rss1) / rank) / (rss1 / df2)
        p = float(stats.f.sf(f_stat, rank, df2))
    out.update(
        statistic=float(f_stat),
        df1=rank,
        df2=int(df2),
        p_value=p,
        effect_size=(rss0 - rss1) / rss0 if rss0 > 0 else np.nan,
        sigma=float(np.sqrt(rss1 / df2)),
        norm2=np.sum(dc**2, axis=0),
    )
    return out


def strata_test(y, x, *, categorical: bool, strata, log_scale: bool = True) -> dict:
    """F-test of X after stratum effects, on the strata in which X varies.

    Parameters
    ----------
    y : array (n,)
        Response, finite.
    x : array (n,)
        Candidate values: integer level codes (categorical) or numbers (continuous).
    categorical : bool
    strata : array (n,) of int
        Stratum code of each row (a single stratum when there is no block).
    log_scale : bool, default True
        Whether a continuous X may enter on ln x (:func:`trend_regressor`); False for
        time/order candidates.

    Returns
    -------
    dict
        ``statistic`` (F), ``df1``, ``df2``, ``p_value``, ``effect_size`` (partial η²),
        ``sigma`` (residual standard deviation), ``mde_norm2`` (‖r‖² of the hardest
        pattern to detect, :mod:`.power`: one level shifted, or a change across the range of
        the trend), ``used`` (boolean mask of the rows tested), ``singletons`` (levels with
        one test), or ``reason`` when the test cannot be made (then ``p_value`` is NaN).
    """
    y = np.asarray(y, float)
    x = np.asarray(x)
    strata = np.asarray(strata)
    varies = pd.Series(x).groupby(strata).transform("nunique").to_numpy() >= 2
    out = {"used": varies, "singletons": [], "p_value": np.nan, "statistic": np.nan}
    out.update(df1=0, df2=0, effect_size=np.nan, sigma=np.nan, mde_norm2=np.nan, reason="")
    if int(varies.sum()) < 4:
        out["reason"] = "the candidate varies within no stratum of the other candidates"
        return out
    y, x, s = y[varies], x[varies], strata[varies]
    cells = None
    if categorical:
        levels, level_of, counts = np.unique(x, return_inverse=True, return_counts=True)
        out["singletons"] = levels[counts == 1].tolist()
        design = (x[:, None] == levels[None, :]).astype(float)
        cells = cell_codes(np.asarray(s), level_of.ravel())
    else:
        design = trend_regressor(x.astype(float), log_scale=log_scale)[:, None]
    res = _nested_f(y, design, s, cells=cells)
    norm2 = res.pop("norm2")
    if res["df1"] and not categorical:
        norm2 = norm2 / np.ptp(design) ** 2  # per change across the observed range
    if res["df1"]:
        res["mde_norm2"] = float(np.nanmin(norm2)) if np.isfinite(norm2).any() else np.nan
    out.update(res)
    return out


def interaction_test(y, a, b, *, strata) -> dict:
    """F-test of the A × B interaction of two categorical candidates after both main effects
    (and the strata): the full cell model against the additive one.

    ``a`` and ``b`` are level codes.  Returns the keys of :func:`strata_test`; ``used`` marks
    every row (a cell of one test still informs the main effects).
    """
    y = np.asarray(y, float)
    a, b, strata = np.asarray(a), np.asarray(b), np.asarray(strata)
    out = {"used": np.ones(y.size, bool), "singletons": [], "p_value": np.nan}
    out.update(statistic=np.nan, df1=0, df2=0, effect_size=np.nan, sigma=np.nan)
    out.update(mde_norm2=np.nan, reason="")
    cells = cell_codes(a, b)  # 0 … k−1, every code present
    n_cells = int(cells.max()) + 1 if cells.size else 0
    if y.size < 6 or n_cells < 4:
        out["reason"] = "fewer than four cells: no interaction to test"
        return out
    dummies = [(codes[:, None] == np.unique(codes)[None, 1:]).astype(float) for codes in (a, b)]
    design = (cells[:, None] == np.arange(n_cells)[None, :]).astype(float)
    res = _nested_f(y, design, strata, nuisance=np.hstack(dummies), cells=cell_codes(strata, cells))
    norm2 = res.pop("norm2")
    ok = np.isfinite(norm2) & (norm2 > 1e-12)
    if res["df1"] and ok.any():
        res["mde_norm2"] = float(norm2[ok].min())
    out.update(res)
    return out


def cell_codes(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Codes of the A × B cells, numbered in order of first appearance.

    For level codes one integer a·(max b + 1) + b per row names the cell (the same numbering
    as factorising the text "a|b", without building the text); other values take that path.
    """
    if a.dtype.kind in "iu" and b.dtype.kind in "iu" and a.size and min(a.min(), b.min()) >= 0:
        return pd.factorize(a.astype(np.int64) * (int(b.max()) + 1) + b)[0]
    return pd.factorize(pd.Series(a).astype(str) + "|" + pd.Series(b).astype(str))[0]


def trend_slope(y, x, *, strata, log_scale: bool = True) -> float:
    """The slope of y on a continuous X within strata (the estimate :func:`strata_test`
    tests: within-stratum centring, on the strata in which X varies), per unit of the
    regressor (:func:`trend_regressor`); NaN when X varies within no stratum."""
    y, x, strata = np.asarray(y, float), np.asarray(x, float), np.asarray(strata)
    varies = pd.Series(x).groupby(strata).transform("nunique").to_numpy() >= 2
    if int(varies.sum()) < 3:
        return float("nan")
    g = trend_regressor(x[varies], log_scale=log_scale)
    s = pd.factorize(strata[varies])[0]
    yc = y[varies] - (np.bincount(s, weights=y[varies]) / np.bincount(s))[s]
    gc = g - (np.bincount(s, weights=g) / np.bincount(s))[s]
    den = float(gc @ gc)
    return float(gc @ yc / den) if den > 0 else float("nan")
