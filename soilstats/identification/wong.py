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

__all__ = ["wong_bekker", "wong_bernstein"]


def wong_bernstein(z, p, *, weights=None) -> tuple[np.ndarray, np.ndarray, int]:
    """(k, n), their covariance, and the number of samples with p ≤ 0 excluded."""
    z, p = np.asarray(z, float), np.asarray(p, float)
    keep = (z > 0) & (p > 0)
    w = p[keep] if weights is None else p[keep] * np.asarray(weights, float)[keep]
    design = np.column_stack([np.ones(keep.sum()), np.log(z[keep])])
    fit = linear_least_squares(design, np.log(p[keep]), weights=w)
    ln_k, n = fit.params.to_numpy()
    k = np.exp(ln_k)
    grad = np.diag([k, 1.0])  # d(k, n)/d(ln k, n)
    return np.array([k, n]), grad @ fit.cov.to_numpy() @ grad.T, int((~keep).sum())


def wong_bekker(b, z, p, *, weights=None) -> tuple[np.ndarray, np.ndarray, int]:
    """(kc, kφ, n), their covariance, and the number of samples with p ≤ 0 excluded."""
    b, z, p = (np.asarray(a, float) for a in (b, z, p))
    keep = (z > 0) & (p > 0)
    sizes = np.unique(b[keep])
    if sizes.size < 2:
        raise ValueError("Wong's Bekker method needs at least two plate sizes b")
    w = p[keep] if weights is None else p[keep] * np.asarray(weights, float)[keep]
    # One intercept ln k_b per plate size and a common slope n.
    design = np.column_stack([(b[keep] == s).astype(float) for s in sizes] + [np.log(z[keep])])
    fit = linear_least_squares(design, np.log(p[keep]), weights=w)
    coef = fit.params.to_numpy()
    cov = fit.cov.to_numpy()
    k_b = np.exp(coef[:-1])
    n = coef[-1]
    cov_kb = np.diag(k_b) @ cov[:-1, :-1] @ np.diag(k_b)
    # k_b = kc·(1/b) + kφ: generalised least squares with the covariance of the k_b.
    inv_b = 1.0 / sizes
    design_k = np.column_stack([inv_b, np.ones_like(inv_b)])
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
