"""Levenberg–Marquardt minimisation of ½‖r(θ)‖² (the paper's Eq. 1).

A compact, dependency-free implementation of Moré's scaled trust-region form of LM
(Moré 1978, "The Levenberg–Marquardt algorithm: implementation and theory"), with Nielsen's
damping update.  Each step solves (JᵀJ + λDᵀD)δ = Jᵀr in the eigenbasis of the scaled normal
equations while that is accurate, and otherwise through the SVD of J D⁻¹, which is stable
where the normal equations are not (κ(JᵀJ) = κ(J)², and the NIST 'higher difficulty'
problems have κ(J) ~ 1e8).  That SVD is taken of the p×p triangle R of a QR factorisation
of J D⁻¹ (same singular values and right vectors, backward stable, and ~4× cheaper than an
SVD of the N×p matrix for the 100k-sample fits of model discovery).  D holds the running
maximum column norms of J, MINPACK's scale-invariant choice, so parameters of very different
magnitude (kc ~ 1e4, n ~ 1) are treated alike.

We own the loop rather than wrap MINPACK so that the stopping reason, the iteration count and
the damping history are explicit in the result, and so one iteration costs one model and one
Jacobian evaluation (scipy's ``least_squares`` adds ~0.3 ms of set-up per call, which is
most of the budget of a 3 000-point Bekker fit).
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.linalg.lapack import dgeqrf, dsyevd

__all__ = ["LMOutcome", "levenberg_marquardt", "scaled_svd"]

_TINY = np.finfo(float).tiny


@dataclass(frozen=True)
class LMOutcome:
    """Raw outcome of :func:`levenberg_marquardt` (the public result is built from it)."""

    params: np.ndarray
    residuals: np.ndarray  # r = w·(y − f) at params
    jacobian: np.ndarray  # ∂(w·f)/∂θ at params, (N, p) (a transposed view of the rows)
    gram: np.ndarray | None  # JᵀJ at params when the loop formed it there, else None
    # (eigenvalues, eigenvectors, (σ, Vᵀ) or None) of D⁻¹JᵀJD⁻¹ and J D⁻¹ at params with
    # D = the column norms of J, when the loop decomposed exactly that matrix there (the
    # covariance of Eq. 4 reuses them rather than decompose it again).
    scaled: tuple | None
    cost: float  # ½‖r‖²
    nfev: int
    njev: int
    niter: int
    converged: bool
    reason: str


def gram_matrix(rows: np.ndarray) -> np.ndarray:
    """JᵀJ from the (p, N) rows of Jᵀ.

    For the few parameters of a soil model, p(p+1)/2 vector dot products beat one BLAS
    ``gemm`` call (~1.2 µs each against ~15 µs for a 3×3 product at N = 3 000: OpenBLAS's
    small-matrix path is slow for a long inner dimension).
    """
    p = rows.shape[0]
    if p > 4:
        return rows @ rows.T
    r = list(rows)
    gram = [[0.0] * p for _ in range(p)]
    for i in range(p):
        for j in range(i + 1):
            gram[i][j] = gram[j][i] = float(r[i] @ r[j])
    return np.array(gram)


# Up to this many elements in Jᵀ, JᵀJ and Jᵀr come from one gemm [Jᵀ; r]·J, copying Jᵀ
# (2.5 µs against 9 µs for dot products at N = 3 000, p = 3); beyond, the copy costs more
# than it saves (N = 100 000: 0.7 ms against 0.15 ms).
_GEMM_ELEMENTS = 60_000


def _gram_and_gradient(
    rows: np.ndarray, r: np.ndarray, block: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(JᵀJ, Jᵀr) from the (p, N) rows of Jᵀ and the residuals r (N,).

    ``block``: a C-ordered (p + 1, N) array whose first p rows are ``rows`` and whose last
    row may be overwritten; r goes there and one product gives both, without a copy.
    """
    p, n = rows.shape
    if block is not None:
        block[p] = r
        both = block @ rows.T
        return both[:p], both[p]
    if p * n <= _GEMM_ELEMENTS and rows.flags.c_contiguous:
        # Two distinct operands: numpy calls gemm, not the syrk it uses for x @ x.T, which
        # OpenBLAS is slow at for a long inner dimension.
        both = np.concatenate((rows, r[None])) @ rows.T
        return both[:p], both[p]
    return gram_matrix(rows), rows @ r


def scaled_svd(rows: np.ndarray, scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(σ, Vᵀ) of the SVD J D⁻¹ = U·diag(σ)·Vᵀ, from the (p, N) rows of Jᵀ and D = ``scale``.

    Householder QR of the N×p matrix J D⁻¹ keeping only R (LAPACK dgeqrf, no Q formed), then
    the SVD of the p×p triangle: R has the singular values and right singular vectors of
    J D⁻¹, and both steps are backward stable, so the small singular values come out as
    accurately as from an SVD of J D⁻¹ itself (LAPACK's dgesdd reduces a tall matrix the same
    way) — without forming U, which is most of that SVD's cost (N = 100 000, p = 8: ~3 ms
    against ~13 ms, one BLAS thread as in the workers of ``soilstats.parallel``).
    """
    p, n = rows.shape
    # A C-ordered (p, N) quotient is an F-ordered N×p matrix: LAPACK works on it in place.
    scaled = np.divide(rows, scale[:, None], order="C")
    qr, _, _, info = dgeqrf(scaled.T, overwrite_a=1)
    if info != 0:  # an invalid argument; not reachable with a finite 2-D array
        _, sv, vt = np.linalg.svd(rows.T / scale, full_matrices=False)
        return sv, vt
    _, sv, vt = np.linalg.svd(np.triu(qr[: min(p, n)]), full_matrices=False)
    return sv, vt


try:
    # The LAPACK gufunc behind np.linalg.eigh, without its Python wrapper (~4 µs at p = 3).
    # It is numpy's own LAPACK, the library its BLAS calls have just warmed; scipy's
    # dsyevd is a second copy of that code, cold in cache (~8 µs more in an interleaved
    # benchmark).  Private to numpy, hence the fallback.
    from numpy.linalg._umath_linalg import eigh_lo as _eigh_lo
except (ImportError, AttributeError):  # pragma: no cover - a numpy without it
    _eigh_lo = None  # type: ignore[assignment,misc]  # a numpy without the private gufunc


def small_eigh(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigen-decomposition (ascending eigenvalues, eigenvectors as columns) of a small
    symmetric matrix, reading its lower triangle, without np.linalg.eigh's wrapper."""
    if _eigh_lo is not None:
        eig, vecs = _eigh_lo(a, signature="d->dd")
        if math.isfinite(float(np.add.reduce(eig))):  # NaN throughout when LAPACK fails
            return eig, vecs
    eig, vecs, info = dsyevd(a)
    if info != 0:
        return np.linalg.eigh(a)  # raises LinAlgError with numpy's message
    return eig, vecs


# Below this cond(J D⁻¹) the step is solved from the scaled normal equations (a p×p eigen-
# problem, cheap): forming JᵀJ costs its smallest eigenvalue a relative error ~cond²·ε, 1e-4
# here, which only perturbs a step that the exact residuals then correct.  Above it the
# squared condition number would spoil the step, so the SVD of J D⁻¹ is used (see
# scaled_svd).  The covariance has its own, stricter limit (see identify.py).
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
    spare_row: bool = False,
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
    spare_row : bool
        ``jacobian`` returns a C-ordered (p + 1, N) array: the p rows of Jᵀ and one more that
        the optimiser may overwrite (with r, so that JᵀJ and Jᵀr come from one product
        without copying J; see :meth:`soilstats.models.base.PowerLawTerms.jacobian_block`).
    """
    theta = np.array(p0, dtype=float)
    r = residual(theta)
    cost = 0.5 * float(r @ r)  # finite exactly when r is (barring overflow of the square)
    if not math.isfinite(cost) and not np.all(np.isfinite(r)):
        return _not_finite_at_start(theta, r)
    state = _first_iterate(theta, r, cost, jacobian, spare_row)
    converged, reason, niter = False, f"iteration limit ({max_iter}) reached", 0
    for niter in range(1, max_iter + 1):  # noqa: B007 (niter is reported after the loop)
        stop = _iteration(state, residual, jacobian, spare_row, xtol, ftol, gtol)
        if stop is not None:
            converged, reason = stop
            break
    s = state
    return LMOutcome(
        s.theta, s.r, s.rows.T, s.gram, s.scaled, s.cost, s.nfev, s.njev, niter, converged, reason
    )


@dataclass(slots=True)
class _Iterate:
    """The state the LM loop carries from one iteration to the next (mutated in place).

    ``rows`` is Jᵀ (p, N) at ``theta`` (``block[:p]`` when the Jacobian comes with a spare
    row); ``gram`` is JᵀJ at ``theta`` once this iteration has formed it, None after a step
    moved ``theta``; ``diag`` is D, the running maximum column norms of J (None before the
    first iteration); ``lam`` and ``nu`` are Nielsen's damping λ and its growth factor ν.
    """

    theta: np.ndarray
    r: np.ndarray
    cost: float  # ½‖r‖²
    rows: np.ndarray
    block: np.ndarray | None
    nfev: int = 1
    njev: int = 1
    gram: np.ndarray | None = None
    scaled: tuple | None = None
    diag: list | None = None
    lam: float | None = None
    nu: float = 2.0


def _not_finite_at_start(theta: np.ndarray, r: np.ndarray) -> LMOutcome:
    """The outcome when r(p0) holds a NaN or inf: nothing to minimise, no Jacobian taken."""
    return LMOutcome(
        theta,
        r,
        np.full((r.size, theta.size), np.nan),
        None,
        None,
        np.inf,
        1,
        0,
        0,
        False,
        "the model is not finite at the starting values",
    )


def _first_iterate(
    theta: np.ndarray, r: np.ndarray, cost: float, jacobian: Callable, spare_row: bool
) -> _Iterate:
    """The loop's state at p0: one residual evaluation done, the Jacobian taken once."""
    block = jacobian(theta) if spare_row else None
    rows = jacobian(theta) if block is None else block[: theta.size]
    return _Iterate(theta, r, cost, rows, block)


def _iteration(
    state: _Iterate,
    residual: Callable,
    jacobian: Callable,
    spare_row: bool,
    xtol: float,
    ftol: float,
    gtol: float,
) -> tuple[bool, str] | None:
    """One LM iteration on ½‖r(θ)‖² (the paper's Eq. 1, J of its Eq. 5): test for
    convergence at θ, then find and take a damped step.

    Returns (converged, reason) when the loop stops at this iteration, else None.  Everything
    works on the p×p Gram matrix G = JᵀJ; J itself (N×p) is touched only by the two products
    of :func:`_gram_and_gradient` (and by the SVD when G is too ill-conditioned), which is
    what keeps an iteration cheap for large N.
    """
    state.gram, g = _gram_and_gradient(state.rows, state.r, state.block)
    # Scalars on p numbers in Python floats: each numpy call on them costs ~0.5 µs.
    g_list, col_sq = g.tolist(), state.gram.diagonal().tolist()
    if not _finite_normal_equations(state.gram, g, g_list, col_sq):
        return False, "the Jacobian is not finite"
    col_norm = [math.sqrt(c) for c in col_sq]
    state.diag = _column_scale(state.diag, col_norm)
    stop = _first_order_stop(state.cost, g_list, col_norm, gtol)
    if stop is not None:
        return stop
    gs = [gk / dk for gk, dk in zip(g_list, state.diag, strict=True)]
    eig, vecs, svd, s2, directions = _scaled_basis(state.gram, state.rows, state.diag)
    proj = [sum(map(operator.mul, v, gs)) for v in directions]
    if state.lam is None:
        state.lam = 1e-3 * max(s2)
    old_cost = state.cost
    accepted, step_small, predicted = _damped_step(
        state, residual, s2, directions, proj, xtol, ftol
    )
    if not accepted:
        if state.diag == col_norm:  # D⁻¹GD⁻¹ at params is what was decomposed
            state.scaled = (eig, vecs, svd)
        return _why_no_step(step_small, predicted, state.cost, xtol, ftol)
    _take_jacobian(state, jacobian, spare_row)
    # MINPACK's ftol on the step just taken: actual and predicted relative reductions both
    # below it.  (The step was not below xtol: that ends _damped_step before any trial.)
    scale = max(old_cost, _TINY)
    if (old_cost - state.cost) / scale <= ftol and predicted / scale <= ftol:
        return True, f"relative cost reduction below ftol={ftol:g}"
    return None


def _finite_normal_equations(
    gram: np.ndarray, g: np.ndarray, g_list: list[float], col_sq: list[float]
) -> bool:
    """Whether JᵀJ and Jᵀr are finite (a NaN or inf in J stops the loop).

    One scalar test first: a NaN or inf in J reaches the diagonal of JᵀJ (and, as
    |Gᵢⱼ| ≤ √(GᵢᵢGⱼⱼ), nothing off it overflows while that is finite), and a sum of finite
    numbers is finite unless it overflows; the elementwise check runs only when that fails.
    """
    return math.isfinite(sum(col_sq) + sum(g_list)) or bool(
        np.isfinite(gram).all() and np.isfinite(g).all()
    )


def _column_scale(diag: list | None, col_norm: list[float]) -> list:
    """D: the running maximum of J's column norms (MINPACK's scale-invariant choice).

    The p×p algebra of an iteration is on Python floats: p is a handful, and each numpy call
    on p numbers costs ~0.5 µs (several when the caches are cold), more than the arithmetic.
    A zero first column norm is raised to the smallest normal float, so D⁻¹ exists.
    """
    if diag is None:
        return [max(c, _TINY) for c in col_norm]
    return [max(d, c) for d, c in zip(diag, col_norm, strict=True)]


def _first_order_stop(
    cost: float, g_list: list[float], col_norm: list[float], gtol: float
) -> tuple[bool, str] | None:
    """(True, reason) when θ is already a stationary point, else None.

    A zero residual is an exact fit.  Otherwise MINPACK's gtol test: the largest cosine of
    the angle between r and a column of J, |Jⱼᵀr| / (‖Jⱼ‖·‖r‖), is at most ``gtol``.
    """
    rnorm = math.sqrt(2 * cost)
    if rnorm == 0.0:
        return True, "zero residual"
    cosine = max(abs(gk) / (ck * rnorm + _TINY) for gk, ck in zip(g_list, col_norm, strict=True))
    if cosine <= gtol:
        return True, f"gradient below gtol={gtol:g}"
    return None


def _scaled_basis(gram: np.ndarray, rows: np.ndarray, diag: list) -> tuple:
    """The orthonormal basis a step is solved in: decompose the scaled normal equations, or
    J D⁻¹ itself when they are ill-conditioned.

    (JᵀJ + λD²)⁻¹Jᵀr is solved in the eigenbasis of D⁻¹JᵀJD⁻¹ while cond(J D⁻¹) stays
    below ``_NORMAL_EQUATIONS_COND``; beyond it forming JᵀJ squares the condition number
    and would spoil the step, so the SVD of J D⁻¹ is taken instead (:func:`scaled_svd`).

    Returns (eig, vecs, svd, s2, directions): the eigen-decomposition of D⁻¹JᵀJD⁻¹; (σ, Vᵀ)
    of J D⁻¹ when it was taken, else None; the squared singular values (the eigenvalues, or
    σ²) and the matching right singular vectors, both as Python lists.  A plain tuple: a
    named one costs ~0.25 µs per iteration to build.
    """
    d = np.array(diag)
    eig, vecs = small_eigh(gram / (d[:, None] * d))
    svd = None
    if eig[0] > eig[-1] / _NORMAL_EQUATIONS_COND**2:
        s2, directions = eig.tolist(), vecs.T.tolist()
    else:
        svd = sv, vt = scaled_svd(rows, d)
        s2, directions = [x * x for x in sv.tolist()], vt.tolist()
    return eig, vecs, svd, s2, directions


def _damped_step(
    state: _Iterate,
    residual: Callable,
    s2: list[float],
    directions: list[list[float]],
    proj: list[float],
    xtol: float,
    ftol: float,
) -> tuple[bool, bool, float]:
    """Raise the damping λ until a step reduces the cost, and take it (Moré 1978, Nielsen).

    ``proj`` holds the scaled gradient D⁻¹Jᵀr in the basis ``directions`` of
    :func:`_scaled_basis`; the step there is cₖ = projₖ / (sₖ² + λ).  A step is accepted
    when the gain ratio ρ = actual / predicted reduction exceeds 1e-4; λ then shrinks by
    max(1/3, 1 − (2ρ − 1)³) and ν resets to 2, else λ grows by ν and ν doubles.

    Returns (accepted, step_small, predicted): whether ``state`` moved to the new point,
    whether the last step was below ``xtol``, and the last predicted reduction
    ½(‖r‖² − ‖r − Jδ‖²).
    """
    diag, cost = state.diag, state.cost
    assert diag is not None and state.lam is not None  # set by _iterate before the step
    theta_list = state.theta.tolist()
    theta_norm = math.sqrt(sum((dk * tk) ** 2 for dk, tk in zip(diag, theta_list, strict=True)))
    while True:
        lam = state.lam
        coef = [pk / (sk + lam) for pk, sk in zip(proj, s2, strict=True)]
        # Predicted reduction of the linear model in that basis: Σ c²(½s² + λ) — a sum of
        # non-negative terms, free of the cancellation of the direct form near the optimum,
        # and no N-length product.  When it or the step is already below tolerance, the
        # trial evaluation could only measure rounding noise: stop rather than spend
        # evaluations on it.
        predicted = sum(c * c * (0.5 * sk + lam) for c, sk in zip(coef, s2, strict=True))
        # ‖Dδ‖ = ‖basis·c‖ = ‖c‖: the basis is orthonormal.
        step_small = math.sqrt(sum(c * c for c in coef)) <= xtol * (theta_norm + xtol)
        if step_small or predicted <= ftol * cost:
            return False, step_small, predicted
        trial = _trial_point(theta_list, coef, directions, diag)
        r_trial = residual(trial)
        state.nfev += 1
        cost_trial = 0.5 * float(r_trial @ r_trial)
        if not math.isfinite(cost_trial):  # NaN or overflow: outside the model's domain
            cost_trial = math.inf
        rho = (cost - cost_trial) / predicted if predicted > 0 else -1.0
        if rho > 1e-4:
            state.theta, state.r, state.cost = trial, r_trial, cost_trial
            state.lam = lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            state.nu = 2.0
            return True, False, predicted
        state.lam = lam * state.nu
        state.nu *= 2.0
        if not math.isfinite(state.lam) or state.lam > 1e300:
            return False, False, predicted


def _trial_point(
    theta_list: list[float], coef: list[float], directions: list[list[float]], diag: list
) -> np.ndarray:
    """θ + δ with Dδ = Σₖ cₖ·vₖ: the step from its coefficients in the scaled basis."""
    scaled_step = [0.0] * len(diag)
    for c, v in zip(coef, directions, strict=True):
        scaled_step = [x + c * vk for x, vk in zip(scaled_step, v, strict=True)]
    return np.array([t + x / dk for t, x, dk in zip(theta_list, scaled_step, diag, strict=True)])


def _why_no_step(
    step_small: bool, predicted: float, cost: float, xtol: float, ftol: float
) -> tuple[bool, str]:
    """(converged, reason) when no step was taken: below a tolerance, or damping exhausted."""
    if step_small:
        return True, f"step below xtol={xtol:g}"
    if predicted <= ftol * cost:
        return True, f"predicted cost reduction below ftol={ftol:g}"
    return False, "no step reduces the cost (damping exhausted)"


def _take_jacobian(state: _Iterate, jacobian: Callable, spare_row: bool) -> None:
    """Jᵀ at the new θ (after an accepted step); the Gram matrix of the old θ is dropped."""
    if spare_row:
        state.block = jacobian(state.theta)
        state.rows = state.block[: state.theta.size]
    else:
        state.rows = jacobian(state.theta)
    state.njev += 1
    state.gram = None
