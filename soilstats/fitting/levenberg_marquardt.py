"""Levenberg–Marquardt minimisation of ½‖r(θ)‖² (the paper's Eq. 1).

A compact, dependency-free implementation of Moré's scaled trust-region form of LM
(Moré 1978, "The Levenberg–Marquardt algorithm: implementation and theory"), with Nielsen's
damping update.  Each step solves (JᵀJ + λDᵀD)δ = Jᵀr through the SVD of J D⁻¹, which is
stable where the normal equations are not (κ(JᵀJ) = κ(J)², and the NIST 'higher difficulty'
problems have κ(J) ~ 1e8).  D holds the running maximum column norms of J, MINPACK's
scale-invariant choice, so parameters of very different magnitude (kc ~ 1e4, n ~ 1) are
treated alike.

We own the loop rather than wrap MINPACK so that the stopping reason, the iteration count and
the damping history are explicit in the result, and so one iteration costs one model and one
Jacobian evaluation (scipy's ``least_squares`` adds ~0.3 ms of set-up per call, which is
most of the budget of a 3 000-point Bekker fit).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.linalg.lapack import dsyevd

__all__ = ["LMOutcome", "levenberg_marquardt"]


@dataclass(frozen=True)
class LMOutcome:
    """Raw outcome of :func:`levenberg_marquardt` (the public result is built from it)."""

    params: np.ndarray
    residuals: np.ndarray  # r = w·(y − f) at params
    jacobian: np.ndarray  # ∂(w·f)/∂θ at params, (N, p) (a transposed view of the rows)
    gram: np.ndarray | None  # JᵀJ at params when the loop formed it there, else None
    cost: float  # ½‖r‖²
    nfev: int
    njev: int
    niter: int
    converged: bool
    reason: str


def _norm(v: np.ndarray) -> float:
    return math.sqrt(float(v @ v))


def gram_matrix(rows: np.ndarray) -> np.ndarray:
    """JᵀJ from the (p, N) rows of Jᵀ.

    For the few parameters of a soil model, p(p+1)/2 vector dot products beat one BLAS
    ``gemm`` call (~1.5 µs each against ~20 µs of call overhead at N = 3 000).
    """
    p = rows.shape[0]
    if p > 4:
        return rows @ rows.T
    gram = np.empty((p, p))
    for i in range(p):
        for j in range(i + 1):
            gram[i, j] = gram[j, i] = rows[i] @ rows[j]
    return gram


def _eigh(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigen-decomposition of a small symmetric matrix (LAPACK dsyevd without numpy's
    ~6 µs of wrapper overhead, which is most of the cost at p = 3)."""
    eig, vecs, info = dsyevd(a)
    if info != 0:
        return np.linalg.eigh(a)  # raises LinAlgError with numpy's message
    return eig, vecs


# Below this cond(J D⁻¹) the step is solved from the scaled normal equations (a p×p eigen-
# problem, cheap); above it the squared condition number would spoil the step, so the SVD of
# J D⁻¹ is used.  The covariance is always formed from the SVD (see identify.py).
_NORMAL_EQUATIONS_COND = 1e6


def levenberg_marquardt(
    residual: Callable[[np.ndarray], np.ndarray],
    jacobian: Callable[[np.ndarray], np.ndarray],
    p0: np.ndarray,
    *,
    xtol: float = 1e-12,
    ftol: float = 1e-14,
    gtol: float = 1e-14,
    max_iter: int = 1000,
) -> LMOutcome:
    """Minimise ½‖r(θ)‖² from ``p0``.

    Parameters
    ----------
    residual : callable
        θ ↦ r(θ) = w·(y − f(X, θ)), shape (N,).
    jacobian : callable
        θ ↦ (∂(w·f)/∂θ)ᵀ, shape (p, N): one row per parameter, so the p×p Gram matrix and
        the gradient are products of contiguous rows.  (The sign convention makes δ = +step.)
    xtol, ftol, gtol : float
        Relative step, relative cost reduction and scaled-gradient tolerances (MINPACK's
        meanings).  Converged when any one holds.
    max_iter : int
        Iterations before giving up; ``converged=False`` is then returned, never a silent value.
    """
    tiny = np.finfo(float).tiny
    theta = np.array(p0, dtype=float)
    r = residual(theta)
    nfev = 1
    if not np.all(np.isfinite(r)):
        return LMOutcome(
            theta,
            r,
            np.full((r.size, theta.size), np.nan),
            None,
            np.inf,
            nfev,
            0,
            0,
            False,
            "the model is not finite at the starting values",
        )
    Jt = jacobian(theta)
    njev = 1
    cost = 0.5 * float(r @ r)
    diag = np.full(theta.size, tiny)
    lam = None
    nu = 2.0
    reason = f"iteration limit ({max_iter}) reached"
    converged = False
    niter = 0
    gram = None
    for niter in range(1, max_iter + 1):  # noqa: B007 (niter is reported after the loop)
        # Everything below works on the p×p Gram matrix G = JᵀJ; J itself (N×p) is touched
        # only by these two products, which is what keeps an iteration cheap for large N.
        gram = gram_matrix(Jt)
        g = Jt @ r
        # One scalar test first (a sum of finite numbers is finite unless it overflows);
        # the elementwise check runs only when that fails.
        if not math.isfinite(float(gram.sum()) + float(g.sum())) and not (
            np.isfinite(gram).all() and np.isfinite(g).all()
        ):
            reason = "the Jacobian is not finite"
            break
        col_norm = np.sqrt(gram.diagonal())
        diag = np.maximum(diag, col_norm)
        rnorm = math.sqrt(2 * cost)
        if rnorm == 0.0:
            converged, reason = True, "zero residual"
            break
        # Scaled gradient: cosine of the angle between r and each column of J (MINPACK gtol).
        if float(np.max(np.abs(g) / (col_norm * rnorm + tiny))) <= gtol:
            converged, reason = True, f"gradient below gtol={gtol:g}"
            break
        gs = g / diag
        eig, vecs = _eigh(gram / np.outer(diag, diag))
        if eig[0] > eig[-1] / _NORMAL_EQUATIONS_COND**2:
            s2, proj, basis = eig, vecs.T @ gs, vecs  # (JᵀJ + λD²)⁻¹Jᵀr in the eigenbasis
        else:
            _, s, vt = np.linalg.svd(Jt.T / diag, full_matrices=False)
            s2, proj, basis = s**2, vt @ gs, vt.T
        if lam is None:
            lam = 1e-3 * float(s2.max())
        step_accepted = False
        step_small = False
        theta_norm = _norm(diag * theta)
        while True:
            coef = proj / (s2 + lam)  # the step in the scaled eigen/singular basis
            step = (basis @ coef) / diag
            # Predicted reduction of the linear model, ½(‖r‖² − ‖r − Jδ‖²), in that basis:
            # Σ c²(½s² + λ) — a sum of non-negative terms, free of the cancellation of the
            # direct form near the optimum, and no N-length product.  When it or the step is
            # already below tolerance, the trial evaluation could only measure rounding
            # noise: stop here rather than spend evaluations on it.
            predicted = float(coef @ (coef * (0.5 * s2 + lam)))
            step_small = _norm(diag * step) <= xtol * (theta_norm + xtol)
            if step_small or predicted <= ftol * cost:
                break
            trial = theta + step
            r_trial = residual(trial)
            nfev += 1
            cost_trial = 0.5 * float(r_trial @ r_trial)
            if not math.isfinite(cost_trial):  # NaN or overflow: outside the model's domain
                cost_trial = np.inf
            actual = cost - cost_trial
            rho = actual / predicted if predicted > 0 else -1.0
            if rho > 1e-4:
                theta, r, old_cost, cost = trial, r_trial, cost, cost_trial
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                step_accepted = True
                break
            lam *= nu
            nu *= 2.0
            if not np.isfinite(lam) or lam > 1e300:
                break
        if not step_accepted:
            if step_small:
                converged, reason = True, f"step below xtol={xtol:g}"
            elif predicted <= ftol * cost:
                converged, reason = True, f"predicted cost reduction below ftol={ftol:g}"
            else:
                reason = "no step reduces the cost (damping exhausted)"
            break
        Jt = jacobian(theta)
        njev += 1
        gram = None
        if step_small:
            converged, reason = True, f"step below xtol={xtol:g}"
            break
        scale = max(old_cost, tiny)
        if (old_cost - cost) / scale <= ftol and predicted / scale <= ftol:
            converged, reason = True, f"relative cost reduction below ftol={ftol:g}"
            break
    return LMOutcome(theta, r, Jt.T, gram, cost, nfev, njev, niter, converged, reason)
