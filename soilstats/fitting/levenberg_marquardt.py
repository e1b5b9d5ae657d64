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

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["LMOutcome", "levenberg_marquardt"]


@dataclass(frozen=True)
class LMOutcome:
    """Raw outcome of :func:`levenberg_marquardt` (the public result is built from it)."""

    params: np.ndarray
    residuals: np.ndarray  # r = w·(y − f) at params
    jacobian: np.ndarray  # ∂(w·f)/∂θ at params
    cost: float  # ½‖r‖²
    nfev: int
    njev: int
    niter: int
    converged: bool
    reason: str


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
        θ ↦ ∂(w·f)/∂θ, shape (N, p).  (The sign convention makes δ = +step.)
    xtol, ftol, gtol : float
        Relative step, relative cost reduction and scaled-gradient tolerances (MINPACK's
        meanings).  Converged when any one holds.
    max_iter : int
        Iterations before giving up; ``converged=False`` is then returned, never a silent value.
    """
    theta = np.array(p0, dtype=float)
    r = residual(theta)
    nfev = 1
    if not np.all(np.isfinite(r)):
        return LMOutcome(theta, r, np.full((r.size, theta.size), np.nan), np.inf, nfev, 0, 0,
                         False, "the model is not finite at the starting values")
    J = jacobian(theta)
    njev = 1
    cost = 0.5 * float(r @ r)
    diag = np.maximum(np.linalg.norm(J, axis=0), np.finfo(float).tiny)
    lam = None
    nu = 2.0
    reason = f"iteration limit ({max_iter}) reached"
    converged = False
    niter = 0
    for niter in range(1, max_iter + 1):
        if not np.all(np.isfinite(J)):
            reason = "the Jacobian is not finite"
            break
        diag = np.maximum(diag, np.linalg.norm(J, axis=0))
        g = J.T @ r
        # Scaled gradient: cosine of the angle between r and each column of J (MINPACK gtol).
        rnorm = np.sqrt(2 * cost)
        if rnorm == 0.0:
            converged, reason = True, "zero residual"
            break
        gnorm = np.max(np.abs(g) / (np.linalg.norm(J, axis=0) * rnorm + np.finfo(float).tiny))
        if gnorm <= gtol:
            converged, reason = True, f"gradient below gtol={gtol:g}"
            break
        U, s, Vt = np.linalg.svd(J / diag, full_matrices=False)
        ur = U.T @ r
        if lam is None:
            lam = 1e-3 * float(s[0] ** 2)
        step_accepted = False
        while True:
            step = (Vt.T @ (s * ur / (s**2 + lam))) / diag
            trial = theta + step
            r_trial = residual(trial)
            nfev += 1
            cost_trial = 0.5 * float(r_trial @ r_trial) if np.all(np.isfinite(r_trial)) else np.inf
            # Predicted reduction of the linear model: ½(‖r‖² − ‖r − Jδ‖²).
            Jstep = J @ step
            predicted = float(Jstep @ r) - 0.5 * float(Jstep @ Jstep)
            actual = cost - cost_trial
            rho = actual / predicted if predicted > 0 else -1.0
            step_small = np.linalg.norm(diag * step) <= xtol * (
                np.linalg.norm(diag * theta) + xtol
            )
            if rho > 1e-4:
                theta, r, old_cost, cost = trial, r_trial, cost, cost_trial
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                step_accepted = True
                break
            lam *= nu
            nu *= 2.0
            if step_small or not np.isfinite(lam) or lam > 1e300:
                break
        if not step_accepted:
            if step_small:
                converged, reason = True, f"step below xtol={xtol:g}"
            else:
                reason = "no step reduces the cost (damping exhausted)"
            break
        J = jacobian(theta)
        njev += 1
        rel_reduction = (old_cost - cost) / max(old_cost, np.finfo(float).tiny)
        if step_small:
            converged, reason = True, f"step below xtol={xtol:g}"
            break
        if rel_reduction <= ftol and predicted / max(old_cost, np.finfo(float).tiny) <= ftol:
            converged, reason = True, f"relative cost reduction below ftol={ftol:g}"
            break
    return LMOutcome(theta, r, J, cost, nfev, njev, niter, converged, reason)
