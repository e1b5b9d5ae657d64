"""Starting values of the LM identification: one home for every model's first guess.

Each is a cheap closed-form estimate that is usually a few LM steps from the optimum; none is a
result.  Used by the paper's identification (:mod:`.sinkage`, :mod:`.shear`) and by the
extended models of discovery, so that both start from the same place.
"""

from __future__ import annotations

import numpy as np

from .wong import wong_start

__all__ = ["janosi_start", "reece_from_bekker", "sinkage_start"]


def sinkage_start(model_name: str, b, z, p) -> np.ndarray:
    """Wong's linearised estimate (Fig. 3) of ``bekker`` / ``bernstein``; ``reece`` mapped.

    b, z [m], p [Pa].  Where Wong's method is undefined (one plate size, no positive p) the
    Bekker start falls back to kc = 0, kφ = median(p/z), n = 1.
    """
    try:
        if model_name == "bernstein":
            return wong_start(None, z, p)
        theta = wong_start(b, z, p)
    except (ValueError, np.linalg.LinAlgError):
        theta = np.array([0.0, np.median(p / np.maximum(z, 1e-9)), 1.0])
    if model_name == "reece":
        return reece_from_bekker(theta, b)
    return theta


def reece_from_bekker(theta, b) -> np.ndarray:
    """(k1, k2, n) of Reece equal to Bekker's (kc, kφ, n) at the geometric-mean plate size.

    (k1 + k2·b)(z/b)^n equals (kc/b + kφ)·z^n when k1 = kc·b^(n−1), k2 = kφ·b^(n−1) at the
    reference b [m]; exact for one plate size, a good start for several.
    """
    kc, kphi, n = theta
    b_ref = float(np.exp(np.mean(np.log(np.unique(np.asarray(b, float))))))
    return np.array([kc * b_ref ** (n - 1), kphi * b_ref ** (n - 1), n])


def janosi_start(sigma, j, tau) -> np.ndarray:
    """(c [Pa], φ [deg], K [m]) for Eq. 13.

    c and tan φ from a straight line τ = c + σ·tan φ through the upper half of j (where the
    curve is near its plateau), K from the 63 % point of each rising sample:
    K = −j / ln(1 − τ/τ_max).
    """
    sigma, j, tau = (np.asarray(v, float) for v in (sigma, j, tau))
    upper = j >= np.median(j)
    design = np.column_stack([np.ones(upper.sum()), sigma[upper]])
    c0, t0 = np.linalg.lstsq(design, tau[upper], rcond=None)[0]
    plateau = c0 + sigma * t0
    ratio = np.clip(tau / np.where(plateau > 0, plateau, np.inf), 0, 0.999)
    rising = (ratio > 0.2) & (ratio < 0.9)
    k0 = np.median(-j[rising] / np.log1p(-ratio[rising])) if rising.any() else np.median(j)
    phi0 = np.degrees(np.arctan(max(t0, 1e-3)))
    return np.array([max(float(c0), 1.0), float(phi0), max(float(k0), 1e-5)])
