"""Wong's classical linearised identification (the comparison method of the paper's Fig. 3).

ln p = ln k + n ln z is fitted by linear least squares with each squared residual weighted by
p² (Wong's remedy for the over-weighting of small sinkages in a plain log–log fit).  For Bekker,
each plate size b gets its own k_b with a common n, then k_b = kc/b + kφ is a straight line in
1/b whose slope and intercept are kc and kφ.  Samples with p ≤ 0 have no logarithm and are
excluded (counted in the result).  The standard deviations are those of the two linear
regressions propagated to (kc, kφ, n) — they describe the linearised problem, not Eq. 9.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..errors import IdentifiabilityError
from ..fitting.linear import linear_least_squares

__all__ = ["wong_bekker", "wong_bernstein", "wong_start"]


def _log_regression(design, log_p, w):
    """Weighted linear least squares of ln p (certified solver) with its covariance."""
    fit = linear_least_squares(design, log_p, weights=w)
    return fit.params.to_numpy(), fit.cov.to_numpy()


def wong_start(b: ArrayLike | None, z: ArrayLike, p: ArrayLike) -> np.ndarray:
    """Wong's estimate alone — Bekker (kc, kφ, n) if ``b`` is given, else Bernstein (k, n).

    The starting values of the LM identification: cheap, and usually a few steps from the
    optimum.  The same estimate as :func:`wong_bekker` / :func:`wong_bernstein`, from the
    normal equations in per-plate sums instead of the certified solver (which also gives a
    covariance a start does not need): the ln p regression with one intercept per plate and
    a common slope is the pooled within-plate slope, and the intercepts the plate means
    (~10× cheaper, equal to ~1e-12 on a paper-size problem).  Raises ValueError where Wong's
    method is undefined (one plate size for Bekker, a single depth, no sample with z, p > 0).
    """
    b_all = np.zeros(np.shape(z)) if b is None else np.asarray(b, float)
    z, p = np.asarray(z, float), np.asarray(p, float)
    keep = (z > 0) & (p > 0)
    if not keep.all():
        b_all, z, p = b_all[keep], z[keep], p[keep]
    sizes = np.unique(b_all)
    if b is not None and sizes.size < 2:
        raise IdentifiabilityError("Wong's Bekker method needs at least two plate sizes b")
    if not sizes.size:
        raise IdentifiabilityError("Wong's method needs samples with z > 0 and p > 0")
    log_z, log_p = np.log(z), np.log(p)
    w = p * p  # each squared residual of ln p weighted by p² (Wong)
    wz = w * log_z
    # Per plate: Σw, Σw·ln z, Σw·ln p, Σw·ln²z, Σw·ln z·ln p.
    member = (b_all == sizes[:, None]).astype(float)
    sw, sz, sp, szz, szp = (member @ np.stack([w, wz, w * log_p, wz * log_z, wz * log_p]).T).T
    within_zz = float(szz.sum() - (sz * sz / sw).sum())
    within_zp = float(szp.sum() - (sz * sp / sw).sum())
    n = within_zp / within_zz
    # One depth per plate leaves only the rounding of the sums (~1e-16 of Σw·ln²z).
    if not (within_zz > 1e-12 * float(szz.sum()) and np.isfinite(n)):
        raise IdentifiabilityError("Wong's method needs more than one sinkage per plate")
    k_b = np.exp((sp - n * sz) / sw)
    if b is None:
        return np.array([float(k_b[0]), n])
    # k_b = kc·(1/b) + kφ: the unweighted line through the plates' k_b.
    inv_b = 1.0 / sizes
    du = inv_b - inv_b.mean()
    kc = float(du @ (k_b - k_b.mean()) / (du @ du))
    return np.array([kc, float(k_b.mean() - kc * inv_b.mean()), n])


def wong_bernstein(
    z: ArrayLike, p: ArrayLike, *, weights: ArrayLike | None = None
) -> tuple[np.ndarray, np.ndarray, int]:
    """(k, n), their covariance, and the number of samples with p ≤ 0 excluded."""
    z, p = np.asarray(z, float), np.asarray(p, float)
    keep = (z > 0) & (p > 0)
    w = p[keep] if weights is None else p[keep] * np.asarray(weights, float)[keep]
    design = np.column_stack([np.ones(keep.sum()), np.log(z[keep])])
    (ln_k, n), cov = _log_regression(design, np.log(p[keep]), w)
    k = np.exp(ln_k)
    grad = np.diag([k, 1.0])  # d(k, n)/d(ln k, n)
    cov = grad @ cov @ grad.T
    return np.array([k, n]), cov, int((~keep).sum())


def wong_bekker(
    b: ArrayLike, z: ArrayLike, p: ArrayLike, *, weights: ArrayLike | None = None
) -> tuple[np.ndarray, np.ndarray, int]:
    """(kc, kφ, n), their covariance, and the number of samples with p ≤ 0 excluded."""
    b, z, p = (np.asarray(a, float) for a in (b, z, p))
    keep = (z > 0) & (p > 0)
    b, z, p = b[keep], z[keep], p[keep]
    sizes = np.unique(b)
    if sizes.size < 2:
        raise IdentifiabilityError("Wong's Bekker method needs at least two plate sizes b")
    w = p if weights is None else p * np.asarray(weights, float)[keep]
    # One intercept ln k_b per plate size (indicator columns) and a common slope n (ln z).
    design = np.empty((b.size, sizes.size + 1))
    for j, size in enumerate(sizes):
        design[:, j] = b == size
    np.log(z, out=design[:, -1])
    coef, cov = _log_regression(design, np.log(p), w)
    k_b = np.exp(coef[:-1])
    n = coef[-1]
    # k_b = kc·(1/b) + kφ: generalised least squares with the covariance of the k_b.
    inv_b = 1.0 / sizes
    design_k = np.column_stack([inv_b, np.ones_like(inv_b)])
    cov_kb = np.diag(k_b) @ cov[:-1, :-1] @ np.diag(k_b)
    if sizes.size == 2:
        kc, kphi = np.linalg.solve(design_k, k_b)
        t = np.linalg.inv(design_k)
    else:
        prec = np.linalg.inv(cov_kb)
        a = design_k.T @ prec @ design_k
        t = np.linalg.solve(a, design_k.T @ prec)
        kc, kphi = t @ k_b
    # Propagate: (kc, kφ) = T·k_b, n from the first regression (cross terms kept).
    full = np.zeros((3, sizes.size + 1))
    full[:2, : sizes.size] = t @ np.diag(k_b)
    full[2, -1] = 1.0
    return np.array([kc, kphi, n]), full @ cov @ full.T, int((~keep).sum())
