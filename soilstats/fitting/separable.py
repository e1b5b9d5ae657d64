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
