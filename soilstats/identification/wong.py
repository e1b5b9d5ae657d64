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

from ..fitting.linear import linear_least_squares

__all__ = ["wong_bekker", "wong_bernstein", "wong_start"]


def _log_regression(design, log_p, w, with_covariance: bool):
    """Weighted linear least squares of ln p: certified solver with covariance, or a plain
    ``lstsq`` when only the estimate is needed (LM starting values, ~50× cheaper)."""
    if with_covariance:
        fit = linear_least_squares(design, log_p, weights=w)
        return fit.params.to_numpy(), fit.cov.to_numpy()
    coef = np.linalg.lstsq(design * w[:, None], log_p * w, rcond=None)[0]
    return coef, None


def wong_start(b, z, p) -> np.ndarray:
    """Wong's estimate alone — Bekker (kc, kφ, n) if ``b`` is given, else Bernstein (k, n).

    The starting values of the LM identification: cheap, and usually a few steps from the
    optimum.  Raises ValueError where Wong's method is undefined (one plate size for Bekker).
    """
    if b is None:
        return _bernstein(z, p, None, with_covariance=False)[0]
    return _bekker(b, z, p, None, with_covariance=False)[0]


def wong_bernstein(z, p, *, weights=None) -> tuple[np.ndarray, np.ndarray, int]:
    """(k, n), their covariance, and the number of samples with p ≤ 0 excluded."""
    return _bernstein(z, p, weights, with_covariance=True)


def _bernstein(z, p, weights, with_covariance):
    z, p = np.asarray(z, float), np.asarray(p, float)
    keep = (z > 0) & (p > 0)
    w = p[keep] if weights is None else p[keep] * np.asarray(weights, float)[keep]
    design = np.column_stack([np.ones(keep.sum()), np.log(z[keep])])
    (ln_k, n), cov = _log_regression(design, np.log(p[keep]), w, with_covariance)
    k = np.exp(ln_k)
    grad = np.diag([k, 1.0])  # d(k, n)/d(ln k, n)
    cov = None if cov is None else grad @ cov @ grad.T
    return np.array([k, n]), cov, int((~keep).sum())


def wong_bekker(b, z, p, *, weights=None) -> tuple[np.ndarray, np.ndarray, int]:
    """(kc, kφ, n), their covariance, and the number of samples with p ≤ 0 excluded."""
    return _bekker(b, z, p, weights, with_covariance=True)


def _bekker(b, z, p, weights, with_covariance):
    b, z, p = (np.asarray(a, float) for a in (b, z, p))
    keep = (z > 0) & (p > 0)
    b, z, p = b[keep], z[keep], p[keep]
    sizes = np.unique(b)
    if sizes.size < 2:
        raise ValueError("Wong's Bekker method needs at least two plate sizes b")
    w = p if weights is None else p * np.asarray(weights, float)[keep]
    # One intercept ln k_b per plate size (indicator columns) and a common slope n (ln z).
    design = np.empty((b.size, sizes.size + 1))
    for j, size in enumerate(sizes):
        design[:, j] = b == size
    np.log(z, out=design[:, -1])
    coef, cov = _log_regression(design, np.log(p), w, with_covariance)
    k_b = np.exp(coef[:-1])
    n = coef[-1]
    # k_b = kc·(1/b) + kφ: generalised least squares with the covariance of the k_b.
    inv_b = 1.0 / sizes
    design_k = np.column_stack([inv_b, np.ones_like(inv_b)])
    if cov is None:  # estimate only: unweighted line through the k_b
        kc, kphi = np.linalg.lstsq(design_k, k_b, rcond=None)[0]
        return np.array([kc, kphi, n]), None, int((~keep).sum())
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
