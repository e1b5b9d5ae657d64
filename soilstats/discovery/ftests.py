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

from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

from ..errors import InputError
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
    "within_blocks_test",
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


class _Within:
    """Rows as the within-stratum F-tests see them (:func:`_nested_f`, :func:`_contrast_f`):
    stratum effects absorbed by centring, and — with ``cells``, codes of rows that share
    their stratum and every column of every model — the rows reduced to cell means weighted
    by their counts m (rows scaled by √m, centred with m-weighted stratum means), with the
    within-cell sum of squares W that every model leaves alike."""

    def __init__(
        self, y: np.ndarray, strata: np.ndarray | pd.Series, cells: np.ndarray | None = None
    ) -> None:
        n = y.size
        self.n = n
        s = pd.factorize(strata)[0]
        self.n_strata = int(s.max()) + 1
        self.within, self.root, self.first = 0.0, None, None
        if cells is not None:
            codes = pd.factorize(cells)[0]
            m = np.bincount(codes).astype(float)
            if m.size < n:
                first = np.empty(m.size, int)
                first[codes] = np.arange(n)  # a row of each cell (all alike)
                mean = np.bincount(codes, weights=y) / m
                self.within = float(np.sum((y - mean[codes]) ** 2))
                y, s = mean, s[first]
                self.first, self.root = first, np.sqrt(m)
        self.y, self.s = y, s
        self.weight = np.ones(s.size) if self.root is None else self.root**2
        self.counts = np.bincount(s, weights=self.weight, minlength=self.n_strata)

    def rows(self, a):
        """``a`` (a column or columns per test) at the rows the test works on."""
        return a if self.first is None else a[self.first]

    def _scaled(self, a):
        return a if self.root is None else a * self.root.reshape(-1, *[1] * (a.ndim - 1))

    def centre(self, a):
        """``a`` (at :meth:`rows`) centred within strata, as the weighted test sees it."""
        shape = [1] * (a.ndim - 1)
        wa = a * self.weight.reshape(-1, *shape)
        sums = np.zeros((self.n_strata, *a.shape[1:]))
        np.add.at(sums, self.s, wa)
        return self._scaled(a - (sums / self.counts.reshape(-1, *shape))[self.s])

    def length(self, a: np.ndarray) -> float:
        """The longest column of ``a`` (at :meth:`rows`) as the test sees it."""
        rows = self._scaled(a)
        return float(np.sqrt(np.max(np.sum(rows**2, axis=0), initial=0.0)))

    def left(self, design, nuisance=None):
        """``(y, design, rank of the nuisance)``: the response and the columns of ``design``
        (per test) as the test sees them — at :meth:`rows`, centred within strata, and
        with what the ``nuisance`` columns carry taken out."""
        design = self.rows(design)
        yc, dc = self.centre(self.y), self.centre(design)
        if nuisance is None or not nuisance.shape[1]:
            return yc, dc, 0
        nuisance = self.rows(nuisance)
        q = _basis(self.centre(nuisance), self.length(nuisance))
        return yc - q @ (q.T @ yc), dc - q @ (q.T @ dc), q.shape[1]


def _basis(a, scale):
    """Orthonormal basis of the columns of ``a``: the left singular vectors whose singular
    value exceeds 1e-9 × ``scale`` (the length of the columns before the strata and
    nuisance were taken out)."""
    if a.shape[1] == 0:
        return a[:, :0]
    u, sv, _ = np.linalg.svd(a, full_matrices=False)
    return u[:, sv > _RANK_TOLERANCE * scale]


def _nested_f(
    y: np.ndarray,
    design: np.ndarray,
    strata: np.ndarray | pd.Series,
    nuisance: np.ndarray | None = None,
    cells: np.ndarray | None = None,
) -> dict:
    """F-test of ``design`` after stratum effects (and ``nuisance`` columns), by
    within-stratum centring (Frisch–Waugh–Lovell).

    Returns ``statistic``, ``df1``, ``df2``, ``p_value``, ``effect_size`` (partial η²),
    ``sigma`` (residual standard deviation of the full model) and ``norm2`` (the squared
    length of each design column after the strata and nuisance are taken out: the pattern
    an effect of one unit leaves, for :mod:`.power`), or ``reason`` when it cannot be made.

    ``cells`` (optional codes) marks rows that share their stratum, design row and nuisance
    row.  Every column of every model is then constant within a cell, so the within-cell sum
    of squares W is left by all of them alike, and the rest is the regression of the cell
    means weighted by the cell counts m (:class:`_Within`).  The same sums of squares, ranks
    (the scaled matrix has the same Gram matrix as the full one) and F, on a few hundred
    cells instead of thousands of tests.

    Ranks are judged against the columns as given, not as left: a column the strata and
    nuisance carry entirely (an interaction the main effects already hold) is left as
    rounding noise, ~1e-16 of its length, and must count for nothing.  Judged against the
    largest of what is left (noise itself, then), noise would count as rank and the test
    would be made on random directions: F(3, 24) with p anywhere in 0..1 for the
    interaction of a factor with a function of itself.
    """
    n = y.size
    w = _Within(y, strata, cells)
    out = {"p_value": np.nan, "statistic": np.nan, "df1": 0, "df2": 0, "reason": ""}
    out.update(effect_size=np.nan, sigma=np.nan, norm2=np.full(design.shape[1], np.nan))
    yc, dc, r0 = w.left(design, nuisance)
    u = _basis(dc, w.length(w.rows(design)))
    rank = u.shape[1]
    df2 = n - w.n_strata - r0 - rank
    if rank < 1:
        out["reason"] = (
            "nothing left to test: the strata and the other effects already carry every "
            "column of this design"
        )
        return out
    if df2 < 2:
        out["reason"] = (
            f"no degrees of freedom left (n = {n}, strata = {w.n_strata}, rank = {rank})"
        )
        return out
    left = yc - u @ (u.T @ yc)
    rss1 = w.within + float(left @ left)
    rss0 = w.within + float(yc @ yc)
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


def _contrast_f(
    y: np.ndarray,
    contrasts: np.ndarray,
    strata: np.ndarray | pd.Series,
    nuisance: np.ndarray | None = None,
    cells: np.ndarray | None = None,
) -> dict:
    """The largest of the one-degree-of-freedom F-tests of each column of ``contrasts``
    (one pattern an effect could take: one cell shifted, one block drifting) after the
    strata and ``nuisance``, its p-value Bonferroni-adjusted over the distinct patterns
    left (two cells of a two-row table leave one pattern, of opposite signs).

    Against an omnibus F of all columns at once, it spends no degrees of freedom on
    patterns the effect does not take: a single deviating cell of a 3 × 3 table is tested
    on one degree of freedom at 9× the level instead of four.  The same keys as
    :func:`_nested_f` (``df1`` = 1, ``statistic`` the largest F, ``norm2`` per column)
    plus ``index`` (the column of the largest F, or None), ``same`` (every column with its
    pattern) and ``patterns`` (the distinct patterns counted)."""
    n = y.size
    w = _Within(y, strata, cells)
    out = {"p_value": np.nan, "statistic": np.nan, "df1": 0, "df2": 0, "reason": ""}
    out.update(effect_size=np.nan, sigma=np.nan, norm2=np.full(contrasts.shape[1], np.nan))
    out.update(index=None, same=[], patterns=0)
    yc, dc, r0 = w.left(contrasts, nuisance)
    contrasts = w.rows(contrasts)
    df2 = n - w.n_strata - r0 - 1
    rss0 = w.within + float(yc @ yc)
    kept: list[np.ndarray] = []
    best: tuple[float, Any] = (-1.0, None)  # (SS, column): a column once one is kept
    norm2 = np.sum(dc**2, axis=0)
    for j in range(dc.shape[1]):
        scale = w.length(contrasts[:, j : j + 1])
        if norm2[j] <= (_RANK_TOLERANCE * scale) ** 2 or scale == 0:
            norm2[j] = np.nan  # carried entirely by the strata and the other effects
            continue
        u = dc[:, j] / np.sqrt(norm2[j])
        if not any(abs(float(u @ v)) > 1 - 1e-9 for v in kept):
            kept.append(u)
        ss = float(u @ yc) ** 2
        if ss > best[0]:
            best = (ss, j)
    if not kept:
        out["reason"] = (
            "nothing left to test: the strata and the other effects already carry every "
            "pattern of this design"
        )
        return out
    if df2 < 2:
        out["reason"] = f"no degrees of freedom left (n = {n}, strata = {w.n_strata})"
        return out
    ss, j = best
    u = dc[:, j] / np.sqrt(norm2[j])
    same = [  # the columns whose pattern is the largest's (two cells of a two-row table)
        i
        for i in range(dc.shape[1])
        if np.isfinite(norm2[i]) and abs(float(u @ dc[:, i]) / np.sqrt(norm2[i])) > 1 - 1e-9
    ]
    rss1 = rss0 - ss
    if rss1 <= 0:
        f_stat, p = (np.inf, 0.0) if rss0 > 0 else (np.nan, np.nan)
    else:
        f_stat = ss / (rss1 / df2)
        p = float(stats.f.sf(f_stat, 1, df2))
    out.update(
        statistic=float(f_stat),
        df1=1,
        df2=int(df2),
        p_value=min(1.0, len(kept) * p) if np.isfinite(p) else p,
        effect_size=ss / rss0 if rss0 > 0 else np.nan,
        sigma=float(np.sqrt(rss1 / df2)) if rss1 > 0 else 0.0,
        norm2=norm2,
        index=j,
        same=same,
        patterns=len(kept),
    )
    return out


def strata_test(
    y: np.ndarray, x: np.ndarray, *, categorical: bool, strata: np.ndarray, log_scale: bool = True
) -> dict:
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


def within_blocks_test(
    y: np.ndarray, x: np.ndarray, *, strata: np.ndarray, min_tests: int = 3
) -> dict:
    """Test of a drift inside one block: the slope of a time/order candidate X in each
    stratum (a plate, a preparation) beside the common slope and the strata, one
    one-degree-of-freedom F-test per stratum with three or more tests and two or more
    values of X, the largest taken and Bonferroni-adjusted (:func:`_contrast_f`).

    The common trend is the candidate's own test (:func:`strata_test`); this one asks
    whether one block drifts apart from it — a plate block whose tests stiffen in run order
    while the others do not, which a common trend over all blocks dilutes.  X enters as
    given (a drift is linear in time or order).  Returns the keys of :func:`strata_test`
    (``mde_norm2`` per change across a block's own range), plus ``block`` (stratum code of
    the block that drifts most, or None) and ``patterns``.
    """
    y, x, strata = np.asarray(y, float), np.asarray(x, float), np.asarray(strata)
    out = {"used": np.zeros(y.size, bool), "singletons": [], "p_value": np.nan}
    out.update(statistic=np.nan, df1=0, df2=0, effect_size=np.nan, sigma=np.nan)
    out.update(mde_norm2=np.nan, reason="", block=None, patterns=1)
    frame = pd.DataFrame({"x": x, "s": strata})
    size = frame.groupby("s")["x"].transform("size").to_numpy()
    spread = frame.groupby("s")["x"].transform("nunique").to_numpy()
    drifting = np.unique(strata[(size >= min_tests) & (spread >= 2)])
    varies = spread >= 2
    out["used"] = varies
    if drifting.size < 2:
        out["reason"] = (
            "fewer than two blocks with three or more tests at two or more values: a drift "
            "inside one block is the candidate's own trend"
        )
        return out
    y, x, s = y[varies], x[varies], strata[varies]
    columns = np.column_stack([np.where(s == b, x, 0.0) for b in drifting])
    res = _contrast_f(y, columns, s, nuisance=x[:, None])
    norm2 = res.pop("norm2")
    if res["df1"]:
        ranges = np.array([np.ptp(x[s == b]) for b in drifting])
        per_range = norm2 / ranges**2  # per change across the block's own range
        ok = np.isfinite(per_range) & (per_range > 0)
        res["mde_norm2"] = float(per_range[ok].min()) if ok.any() else np.nan
    index = res.pop("index")
    res.pop("same")
    res["block"] = None if index is None else drifting[index]
    out.update(res)
    return out


#: How :func:`interaction_test` tests: ``"cell"`` (one deviating cell, :func:`_contrast_f`)
#: or ``"omnibus"`` (every cell at once, the F-test until issue #35).
INTERACTION_TESTS = ("cell", "omnibus")


def interaction_test(
    y: np.ndarray, a: np.ndarray, b: np.ndarray, *, strata: np.ndarray, test: str = "cell"
) -> dict:
    """Test of the A × B interaction of two categorical candidates after both main effects
    (and the strata), against the additive model.

    ``test="cell"`` (the default): one deviating cell — each cell's indicator after the
    additive model is a one-degree-of-freedom F-test, the largest is taken and its p
    Bonferroni-adjusted over the distinct patterns (:func:`_contrast_f`).  An operator who
    leaves one preparation stiffer shifts one cell; the omnibus F spreads its test over
    every pattern of the table ((I−1)(J−1) degrees of freedom).  ``"omnibus"``: the full
    cell model against the additive one (every pattern at once).  In a 2 × 2 table the two
    are the same test.

    ``a`` and ``b`` are level codes.  Returns the keys of :func:`strata_test`, plus
    ``cell`` (code of the deviating cell, or None), ``cells`` (every cell with its
    pattern: both cells of a column in a two-row table) and ``patterns`` (the distinct
    patterns Bonferroni counted, 1 for the omnibus); ``used`` marks every row (a cell of one test
    still informs the main effects).
    """
    if test not in INTERACTION_TESTS:
        raise InputError(f"test must be one of {INTERACTION_TESTS}, got {test!r}")
    y = np.asarray(y, float)
    a, b, strata = np.asarray(a), np.asarray(b), np.asarray(strata)
    out = {"used": np.ones(y.size, bool), "singletons": [], "p_value": np.nan}
    out.update(statistic=np.nan, df1=0, df2=0, effect_size=np.nan, sigma=np.nan)
    out.update(mde_norm2=np.nan, reason="", cell=None, cells=[], patterns=1)
    cells = cell_codes(a, b)  # 0 … k−1, every code present
    n_cells = int(cells.max()) + 1 if cells.size else 0
    if y.size < 6 or n_cells < 4:
        out["reason"] = "fewer than four cells: no interaction to test"
        return out
    dummies = [(codes[:, None] == np.unique(codes)[None, 1:]).astype(float) for codes in (a, b)]
    design = (cells[:, None] == np.arange(n_cells)[None, :]).astype(float)
    args = dict(nuisance=np.hstack(dummies), cells=cell_codes(strata, cells))
    if test == "omnibus":
        res = _nested_f(y, design, strata, **args)
    else:
        res = _contrast_f(y, design, strata, **args)
        res["cell"] = res.pop("index")
        res["cells"] = res.pop("same")
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


def trend_slope(
    y: np.ndarray, x: np.ndarray, *, strata: np.ndarray, log_scale: bool = True
) -> float:
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
