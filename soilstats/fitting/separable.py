"""Variable projection for the power-law sinkage models: a better start for Levenberg–Marquardt.

Bekker (Eq. 7) and Bernstein (Eq. 8) are *linear* in all parameters but the exponent n:
p = Σ a_i·g_i(x)·z^n with (a_1, a_2) = (kc, kφ), g = (1/b, 1) for Bekker, a_1 = k, g = 1 for
Bernstein.  For fixed n the a_i follow from a q×q linear solve, so the weighted least-squares
problem of Eq. 1 reduces to one dimension in n (Golub & Pereyra 1973).  Gauss–Newton on that
reduced functional, with Kaufman's Jacobian, reaches the optimum from Wong's start in a few
cheap iterations; :func:`soilstats.identify` then runs its full LM from there, which confirms
convergence with its own stopping rules in one iteration and supplies the covariance (Eq. 4).
The minimum is the same — only the path to it is shorter.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .levenberg_marquardt import gram_matrix

__all__ = ["refine_exponent"]


def _solve_small(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """gram⁻¹·rhs for q ≤ 2 in closed form (numpy's solve costs more than the arithmetic)."""
    q = gram.shape[0]
    if q == 1:
        return rhs / gram[0, 0]
    if q == 2:
        (g00, g01), (_, g11) = gram
        det = g00 * g11 - g01 * g01
        if not det > 1e-13 * g00 * g11:  # collinear basis columns (or NaN)
            raise np.linalg.LinAlgError("singular basis")
        return np.array([g11 * rhs[0] - g01 * rhs[1], g00 * rhs[1] - g01 * rhs[0]]) / det
    return np.linalg.solve(gram, rhs)


def _project(rows: np.ndarray, wy: np.ndarray):
    """Linear coefficients a(n), residual r = wy − aᵀU, ½‖r‖², and the q×q Gram matrix."""
    gram = gram_matrix(rows)
    a = _solve_small(gram, rows @ wy)
    r = wy - a @ rows
    return a, r, 0.5 * float(r @ r), gram


def refine_exponent(
    basis: Callable[[float], np.ndarray],
    log_z: np.ndarray,
    wy: np.ndarray,
    theta0: np.ndarray,
    *,
    ftol: float,
    max_iter: int = 50,
) -> tuple[np.ndarray, int]:
    """Minimise ½‖wy − a(n)ᵀU(n)‖² over the exponent n (the last parameter of ``theta0``).

    Parameters
    ----------
    basis : callable
        n ↦ U(n), the (q, N) weighted basis rows w·g_i(x)·z^n.
    log_z : numpy.ndarray
        ln z (N,), so that ∂U/∂n = U·ln z.
    wy : numpy.ndarray
        Weighted measurements w·y (N,).
    theta0 : numpy.ndarray
        Start (a_1 … a_q, n); only n is used.
    ftol : float
        Stop when the predicted reduction of the cost falls below ``ftol`` × cost.

    Returns
    -------
    (theta, iterations)
        The best (a_1 … a_q, n) reached — ``theta0`` itself when the reduced problem cannot
        be solved (singular basis, non-finite values).  Never a verdict: the full LM that
        follows decides convergence.
    """
    best = np.asarray(theta0, dtype=float)
    n = float(best[-1])
    iteration = 0
    try:
        with np.errstate(all="ignore"):
            rows = basis(n)
            a, r, cost, gram = _project(rows, wy)
            if not math.isfinite(cost):
                return best, 0
            for iteration in range(1, max_iter + 1):  # noqa: B007 (reported)
                # ∂(aᵀU)/∂n = (fitted)·ln z; its part orthogonal to the basis is Kaufman's
                # Jacobian of the reduced residual, and −r·v is the exact gradient (r ⟂ U).
                v = (wy - r) * log_z
                pv = v - _solve_small(gram, rows @ v) @ rows
                curvature = float(pv @ pv)
                slope = -float(r @ v)
                if not (curvature > 0 and math.isfinite(curvature) and math.isfinite(slope)):
                    break
                # A thousandth of the LM's tolerance: one more (quadratically convergent, cheap)
                # step, so the LM that follows finds nothing left to do.
                if 0.5 * slope * slope / curvature <= 1e-3 * ftol * cost:
                    break
                step = -slope / curvature
                for _ in range(40):  # halve until the cost decreases
                    rows_t = basis(n + step)
                    a_t, r_t, cost_t, gram_t = _project(rows_t, wy)
                    if math.isfinite(cost_t) and cost_t < cost:
                        break
                    step *= 0.5
                else:
                    break
                n, rows, a, r, cost, gram = n + step, rows_t, a_t, r_t, cost_t, gram_t
            if np.all(np.isfinite(a)):
                best = np.append(a, n)
    except np.linalg.LinAlgError:
        pass  # a singular basis: the full LM starts from the last good point instead
    return best, iteration


def _solve_rows(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """gram_b⁻¹·rhs_b for every row b (q ≤ 2 in closed form); NaN for a singular row, which
    the caller then reports as not converged (one collinear resample must not sink the rest)."""
    q = gram.shape[-1]
    if q == 1:
        return rhs / gram[:, 0]
    if q == 2:
        g00, g01, g11 = gram[:, 0, 0], gram[:, 0, 1], gram[:, 1, 1]
        det = g00 * g11 - g01 * g01
        det = np.where(det > 1e-13 * g00 * g11, det, np.nan)
        return (
            np.column_stack([g11 * rhs[:, 0] - g01 * rhs[:, 1], g00 * rhs[:, 1] - g01 * rhs[:, 0]])
            / det[:, None]
        )
    return np.linalg.solve(gram, rhs[..., None])[..., 0]


#: Rows × samples a caller should hand :func:`fit_separable_batch` per call: bounds its memory
#: (a few MB whatever the campaign's size) and keeps the arrays in cache (100k beat 1M by 20 %).
BATCH_ELEMENTS = 100_000


def fit_separable_batch(
    basis0: np.ndarray,
    log_z: np.ndarray,
    y: np.ndarray,
    weights: np.ndarray,
    n0: float,
    *,
    ftol: float = 1e-14,
    max_iter: int = 50,
) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least squares of p = aᵀg(x)·z^n for many weightings at once (rows of
    ``weights``): the bootstrap's resamples, each refitted exactly.

    The same reduced problem as :func:`refine_exponent` (a(n) projected out, Gauss–Newton in n
    with Kaufman's Jacobian, step halving), vectorised over rows: one pass over the (B, N)
    arrays per iteration instead of B small fits.

    Parameters
    ----------
    basis0 : numpy.ndarray
        (q, N) the unweighted basis g_i(x) (1/b and 1 for Bekker, 1 for Bernstein).
    log_z : numpy.ndarray
        ln z (N,).
    y : numpy.ndarray
        Measurements (N,).
    weights : numpy.ndarray
        (B, N) per-row sample weights w (Eq. 1); a zero weight leaves the sample out.
    n0 : float
        Start of the exponent for every row.
    ftol : float
        A row has converged when the predicted reduction of its cost is ≤ ``ftol`` × cost.

    Returns
    -------
    (theta, converged)
        (B, q + 1) estimates (a_1 … a_q, n) and a (B,) mask; rows that did not converge (or
        met a singular basis) hold NaN and are the caller's to refit another way.
    """
    weights = np.asarray(weights, float)
    rows_b, q = weights.shape[0], basis0.shape[0]
    n = np.full(rows_b, float(n0))
    theta = np.full((rows_b, q + 1), np.nan)
    converged = np.zeros(rows_b, bool)
    active = np.arange(rows_b)
    wy_all = weights * y

    def project(idx, n_idx):
        we = np.exp(np.multiply.outer(n_idx, log_z))
        we *= weights[idx]
        u = we[:, None, :] * basis0[None]  # (B, q, N) weighted basis rows w·g·z^n
        gram = np.einsum("bkn,bln->bkl", u, u)
        wy = wy_all[idx]
        a = _solve_rows(gram, np.einsum("bkn,bn->bk", u, wy))
        fitted = np.einsum("bk,bkn->bn", a, u)
        r = wy - fitted
        return u, gram, a, fitted, r, 0.5 * np.einsum("bn,bn->b", r, r)

    with np.errstate(all="ignore"):
        u, gram, a, fitted, r, cost = project(active, n)
        for _ in range(max_iter):
            v = fitted * log_z
            coef = _solve_rows(gram, np.einsum("bkn,bn->bk", u, v))
            pv = v - np.einsum("bk,bkn->bn", coef, u)
            curvature = np.einsum("bn,bn->b", pv, pv)
            slope = -np.einsum("bn,bn->b", r, v)
            sane = np.isfinite(cost) & np.isfinite(slope) & (curvature > 0)
            done = sane & (0.5 * slope**2 / curvature <= ftol * cost)
            theta[active[done]] = np.column_stack([a[done], n[active[done]]])
            converged[active[done]] = True
            keep = sane & ~done
            active, u, gram, a, fitted, r, cost = (
                active[keep],
                u[keep],
                gram[keep],
                a[keep],
                fitted[keep],
                r[keep],
                cost[keep],
            )
            if not active.size:
                break
            step = -slope[keep] / curvature[keep]
            pending = np.ones(active.size, bool)
            for _ in range(40):  # halve each row's step until its cost decreases
                idx = np.flatnonzero(pending)
                trial = project(active[idx], n[active[idx]] + step[idx])
                better = np.isfinite(trial[5]) & (trial[5] < cost[idx])
                took = idx[better]
                n[active[took]] += step[took]
                for arr, new in zip((u, gram, a, fitted, r, cost), trial, strict=True):
                    arr[took] = new[better]
                pending[took] = False
                step[idx[~better]] *= 0.5
                if not pending.any():
                    break
            # A row whose step never reduced its cost is left unconverged: the caller refits
            # it another way rather than trusting a point the criterion has not accepted.
            moved = ~pending
            active, u, gram, a, fitted, r, cost = (
                x[moved] for x in (active, u, gram, a, fitted, r, cost)
            )
            if not active.size:
                break
    return theta, converged
