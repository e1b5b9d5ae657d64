"""Many refits of a power-law model that differ only in how often each test counts.

The cluster bootstrap over tests (:mod:`soilstats.identification.bootstrap`) refits the
pooled data B times, resample b weighting test i by how often it was drawn, c_bi.  For the
separable power laws — Bekker (Eq. 7) and Bernstein (Eq. 8), p = aᵀg·z^n with the basis g
(1/b and 1, or 1) constant within a test — everything a refit needs is a handful of per-test
sums of z^n and z^2n:

    A_j(i; n) = Σ_s∈i w_s² (ln z_s)^j z_s^2n   (j = 0, 1, 2),
    B_j(i; n) = Σ_s∈i w_s² y_s (ln z_s)^j z_s^n  (j = 0, 1),     C_i = Σ_s∈i w_s² y_s².

With them the Gram matrix, the projected coefficients a(n), the cost, its slope in n and
Kaufman's Gauss–Newton curvature of the variable-projection problem (Golub & Pereyra 1973)
follow per resample from B×T arrays, never B×N ones.  The sums depend on n through
z^n = e^{n m_i}·e^{n0 u}·e^{δu} (m_i the centre of ln z in test i, u = ln z − m_i,
δ = n − n0), and e^{δu} is a Taylor series: per-test moments Σ w² u^k e^{2 n0 u} (…) computed
once turn every later evaluation into a (B×K)·(K×T) matrix product.  K = 30 terms keep the
truncation below 1e-20 while |2δ|·max|u| ≤ 2; a resample whose exponent strays further is
returned unconverged for the caller to refit exactly.

Cost per Gauss–Newton iteration: O(B·T·K) instead of O(B·N) exponentials — for a campaign
with 100 samples per test about 20× less arithmetic, all of it in BLAS.
"""

from __future__ import annotations

from math import factorial

import numpy as np

from .separable import solve_rows

__all__ = ["fit_clustered_resamples", "fit_linear_resamples"]

#: Taylor terms of e^{δu}; with |2δu| ≤ _REACH the remainder is below 2^31/31! ≈ 3e-25.
_TERMS = 31
_REACH = 2.0
#: Elements of one (rows × tests) working array.
_BLOCK_ELEMENTS = 500_000
_INV_FACTORIAL = np.array([1.0 / factorial(k) for k in range(_TERMS)])


class _TestMoments:
    """The per-test moments of one pooled data set around the exponent n0."""

    def __init__(self, log_z, y, w2, test_index, n_tests, n0):
        order = np.argsort(test_index, kind="stable")
        idx = test_index[order]
        starts = np.flatnonzero(np.r_[True, idx[1:] != idx[:-1]])
        log_z, y, w2 = log_z[order], y[order], w2[order]
        lo = np.minimum.reduceat(log_z, starts)
        hi = np.maximum.reduceat(log_z, starts)
        self.centre = 0.5 * (lo + hi)  # m_i
        # The widest test's half range of ln z: how far a Taylor step in n may go.
        self.half_range = float(np.maximum(0.5 * (hi - lo), 1e-300).max())
        u = log_z - np.repeat(self.centre, np.diff(np.r_[starts, log_z.size]))
        self.n0 = float(n0)
        base_a = w2 * np.exp(2.0 * self.n0 * u)
        base_b = w2 * y * np.exp(self.n0 * u)
        # (j, test, k): Σ_s base·(ln z)^j·u^k; ln z = m + u is expanded on the fly.
        self.a = np.empty((3, n_tests, _TERMS))
        self.b = np.empty((2, n_tests, _TERMS))
        log_z_squared = log_z**2
        power = np.ones_like(u)
        for k in range(_TERMS):
            # base·u^k once per k, then ·(ln z)^j (left to right, as one product would be;
            # the j = 0 factor is 1).
            term_a, term_b = base_a * power, base_b * power
            self.a[0, :, k] = np.add.reduceat(term_a, starts)
            self.a[1, :, k] = np.add.reduceat(term_a * log_z, starts)
            self.a[2, :, k] = np.add.reduceat(term_a * log_z_squared, starts)
            self.b[0, :, k] = np.add.reduceat(term_b, starts)
            self.b[1, :, k] = np.add.reduceat(term_b * log_z, starts)
            power = power * u
        self.c = np.add.reduceat(w2 * y * y, starts)
        self.a *= _INV_FACTORIAL  # fold 1/k! in once
        self.b *= _INV_FACTORIAL

    def sums(self, n: np.ndarray) -> tuple[np.ndarray, ...]:
        """(A_0, A_1, A_2, B_0, B_1), each (B, T), at the exponents n (B,)."""
        delta = n - self.n0
        k = np.arange(_TERMS)
        p2 = (2.0 * delta)[:, None] ** k  # (B, K)
        p1 = delta[:, None] ** k
        scale_a = np.exp(2.0 * np.multiply.outer(n, self.centre))  # e^{2n m_i}, (B, T)
        scale_b = np.exp(np.multiply.outer(n, self.centre))
        a = [scale_a * (p2 @ self.a[j].T) for j in range(3)]
        b = [scale_b * (p1 @ self.b[j].T) for j in range(2)]
        return (*a, *b)

    def within_reach(self, n: np.ndarray) -> np.ndarray:
        return np.abs(2.0 * (n - self.n0)) * self.half_range <= _REACH


def fit_clustered_resamples(
    basis_per_test: np.ndarray,
    log_z: np.ndarray,
    y: np.ndarray,
    weights: np.ndarray,
    test_index: np.ndarray,
    counts: np.ndarray,
    n0: float,
    *,
    rtol: float = 1e-14,
    max_iter: int = 50,
) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least squares of p = aᵀg_i·z^n for every row of ``counts`` (see module doc).

    Parameters
    ----------
    basis_per_test : numpy.ndarray
        (T, q) the basis g_i of each test (Bekker: 1/b [1/m] and 1; Bernstein: 1).
    log_z : numpy.ndarray
        ln z (N,), z [m] > 0.
    y : numpy.ndarray
        Measured pressures (N,) [Pa].
    weights : numpy.ndarray
        Sample weights w (N,) of Eq. 1 (the paper's 1/max p per test).
    test_index : numpy.ndarray
        Test of each sample, integers 0 … T−1 (every test present).
    counts : numpy.ndarray
        (B, T) how often resample b drew test i (its squared weights are c_bi·w²).
    n0 : float
        The exponent every refit starts from (the full-data estimate); also the centre of
        the Taylor expansion.
    rtol : float
        A row has converged when Gauss–Newton's predicted cost reduction is ≤ rtol × its
        cost, or its slope in n is below what the sums resolve.

    Returns
    -------
    (theta, converged)
        (B, q + 1) estimates (a_1 … a_q, n) and a (B,) mask.  Rows that did not converge —
        a singular basis, an exponent beyond the expansion's reach, no decreasing step — hold
        NaN: the caller refits those exactly.
    """
    g = np.asarray(basis_per_test, float)
    counts = np.asarray(counts, float)
    moments = _TestMoments(
        np.asarray(log_z, float),
        np.asarray(y, float),
        np.asarray(weights, float) ** 2,
        np.asarray(test_index),
        counts.shape[1],
        n0,
    )
    theta = np.full((counts.shape[0], g.shape[1] + 1), np.nan)
    converged = np.zeros(counts.shape[0], bool)
    # Rows in blocks: the working arrays are (rows, T), so memory stays a few tens of MB
    # whatever the number of tests.
    block = max(1, _BLOCK_ELEMENTS // max(counts.shape[1], 1))
    for first in range(0, counts.shape[0], block):
        rows = slice(first, first + block)
        theta[rows], converged[rows] = _fit_rows(moments, g, counts[rows], n0, rtol, max_iter)
    return theta, converged


def _fit_rows(moments, g, counts, n0, rtol, max_iter):
    """Gauss–Newton in n with step halving for each row of ``counts`` (see the caller)."""
    n_rows = counts.shape[0]
    q = g.shape[1]
    pairs = [(i, j) for i in range(q) for j in range(i, q)]
    g_pairs = np.column_stack([g[:, i] * g[:, j] for i, j in pairs])  # (T, q(q+1)/2)
    total = counts @ moments.c  # Σ c·w²y², the scale of every cost

    def state(n, c):
        """Coefficients, cost, slope and curvature of the reduced problem at n, per row."""
        a0, a1, a2, b0, b1 = moments.sums(n)
        flat = (c * a0) @ g_pairs
        gram = np.empty((n.size, q, q))
        for col, (i, j) in enumerate(pairs):
            gram[:, i, j] = gram[:, j, i] = flat[:, col]
        rhs = (c * b0) @ g
        coef = solve_rows(gram, rhs)
        cost = 0.5 * (c @ moments.c - np.einsum("bq,bq->b", rhs, coef))
        phi = coef @ g.T  # aᵀg_i, (B, T)
        slope = -np.einsum("bt,bt->b", c * phi, b1 - phi * a1)
        # The slope is a difference of two nearly equal sums at the optimum: what it resolves.
        slope_noise = 1e-13 * np.einsum("bt,bt->b", c, np.abs(phi * b1))
        uv = (c * phi * a1) @ g  # U·v
        curvature = np.einsum("bt,bt->b", c * phi * phi, a2) - np.einsum(
            "bq,bq->b", uv, solve_rows(gram, uv)
        )
        return coef, cost, slope, curvature, slope_noise

    n = np.full(n_rows, float(n0))
    theta = np.full((n_rows, q + 1), np.nan)
    converged = np.zeros(n_rows, bool)
    active = np.arange(n_rows)
    with np.errstate(all="ignore"):
        coef, cost, slope, curvature, noise = state(n, counts)
        for _ in range(max_iter):
            sane = (
                np.isfinite(cost)
                & np.isfinite(slope)
                & (curvature > 0)
                & np.all(np.isfinite(coef), axis=1)
            )
            predicted = 0.5 * slope**2 / curvature
            done = sane & ((predicted <= rtol * cost) | (np.abs(slope) <= noise))
            rows = active[done]
            theta[rows, :q], theta[rows, q] = coef[done], n[rows]
            converged[rows] = True
            keep = sane & ~done
            if not keep.any():
                break
            active, coef, cost, slope, curvature, noise, predicted = (
                v[keep] for v in (active, coef, cost, slope, curvature, noise, predicted)
            )
            # A reduction below the cost's resolution (it is Σc·w²y² − hᵀa, a difference)
            # cannot be seen by comparing costs: such a step is taken as Gauss–Newton gives it.
            unresolved = predicted <= 1e-14 * total[active]
            step = -slope / curvature
            pending = np.ones(active.size, bool)
            for _ in range(30):  # halve each row's step until its cost decreases
                idx = np.flatnonzero(pending)
                trial_n = n[active[idx]] + step[idx]
                trial = state(trial_n, counts[active[idx]])
                reach = moments.within_reach(trial_n)
                better = reach & np.isfinite(trial[1]) & ((trial[1] < cost[idx]) | unresolved[idx])
                took = idx[better]
                n[active[took]] = trial_n[better]
                for arr, new in zip((coef, cost, slope, curvature, noise), trial, strict=True):
                    arr[took] = new[better]
                pending[took] = False
                step[idx[~better]] *= 0.5
                if not pending.any():
                    break
            moved = ~pending  # a row whose step never helped is left for an exact refit
            active, coef, cost, slope, curvature, noise = (
                v[moved] for v in (active, coef, cost, slope, curvature, noise)
            )
            if not active.size:
                break
    return theta, converged


def fit_linear_resamples(
    design: np.ndarray,
    y: np.ndarray,
    weights: np.ndarray,
    test_index: np.ndarray,
    counts: np.ndarray,
    *,
    max_condition: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weighted linear least squares y ≈ X·β for every row of ``counts``, in closed form.

    The linear counterpart of :func:`fit_clustered_resamples` (Mohr–Coulomb, Eq. 15, is
    linear in c and tan φ): resample b weights test i's samples by c_bi·w², so its normal
    equations are ``counts @`` per-test sums of w²·XᵀX and w²·Xᵀy — (B, T)·(T, p²) products,
    never (B, N) arrays.  The columns other than a constant one are centred at their
    full-data weighted mean first (σ in Pa beside the intercept would square a condition of
    10³–10⁴ into the normal equations); β is mapped back exactly.

    Parameters
    ----------
    design : numpy.ndarray
        (N, p) the design X (for Mohr–Coulomb: 1 and σ [Pa]).
    y, weights : numpy.ndarray
        (N,) measurements and sample weights w.
    test_index : numpy.ndarray
        Test of each sample, integers 0 … T−1.
    counts : numpy.ndarray
        (B, T) how often resample b drew test i.
    max_condition : float
        A resample whose column-equilibrated design has cond(X D⁻¹) above this does not
        determine β (the identification's rank rule, ``RANK_CONDITION_LIMIT``).  The
        condition is read from the eigenvalues of the Gram matrix, which resolve it to about
        1e7; beyond that it reads inf, so such a resample fails where the LM's limit is 1e12
        (the bootstrap screens resamples by the spread of σ first, which removes them).

    Returns
    -------
    (beta, determined, condition)
        (B, p) coefficients (NaN where not determined), the (B,) mask of determined rows and
        (B,) cond(X D⁻¹) of the *uncentred* design, as the identification measures it.
    """
    x = np.asarray(design, float)
    w2 = np.asarray(weights, float) ** 2
    test_index = np.asarray(test_index)
    counts = np.asarray(counts, float)
    n_rows, n_tests = counts.shape
    p = x.shape[1]
    constant = np.flatnonzero(np.all(x == x[:1], axis=0))
    shift = np.zeros(p)
    if constant.size == 1:
        shift = np.where(np.arange(p) == constant[0], 0.0, (w2 @ x) / w2.sum())
    xc = x - shift
    # Per-test sums of w²·xc_j·xc_k (j ≤ k) and w²·xc_j·y.
    gram_t = np.empty((n_tests, p, p))
    for j in range(p):
        for k in range(j, p):
            gram_t[:, j, k] = gram_t[:, k, j] = np.bincount(
                test_index, weights=w2 * xc[:, j] * xc[:, k], minlength=n_tests
            )
    rhs_t = np.column_stack(
        [np.bincount(test_index, weights=w2 * xc[:, j] * y, minlength=n_tests) for j in range(p)]
    )
    gram = (counts @ gram_t.reshape(n_tests, p * p)).reshape(n_rows, p, p)
    rhs = counts @ rhs_t
    # cond(X D⁻¹) of the uncentred design: X = xc·M with M = I + e_k·shiftᵀ/x_k.
    unmix = np.eye(p)
    if constant.size == 1:
        unmix[constant[0]] += shift / x[0, constant[0]]
    condition = _scaled_condition(unmix.T @ gram @ unmix)
    determined = (condition <= max_condition) & (_scaled_condition(gram) <= max_condition)
    beta = np.full((n_rows, p), np.nan)
    if determined.any():
        g, r = gram[determined], rhs[determined]
        scale = np.sqrt(np.einsum("bii->bi", g))
        solved = np.linalg.solve(
            g / (scale[:, :, None] * scale[:, None, :]), (r / scale)[:, :, None]
        )[:, :, 0]
        solved /= scale
        if constant.size == 1:  # back to the uncentred intercept
            k = constant[0]
            solved[:, k] -= (solved @ shift) / x[0, k]
        beta[determined] = solved
    determined &= np.isfinite(beta).all(axis=1)
    return beta, determined, condition


def _scaled_condition(gram: np.ndarray) -> np.ndarray:
    """(B,) cond(X D⁻¹) = √(λmax/λmin) of each column-equilibrated Gram matrix XᵀX (inf when
    singular or not finite)."""
    diag = np.einsum("bii->bi", gram)
    out = np.full(gram.shape[0], np.inf)
    good = np.isfinite(gram).all(axis=(1, 2)) & (diag > 0).all(axis=1)
    if good.any():
        scale = np.sqrt(diag[good])
        eig = np.linalg.eigvalsh(gram[good] / (scale[:, :, None] * scale[:, None, :]))
        with np.errstate(divide="ignore", invalid="ignore"):
            out[good] = np.where(eig[:, 0] > 0, np.sqrt(eig[:, -1] / eig[:, 0]), np.inf)
    return out
