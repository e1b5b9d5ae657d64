"""Starting values of the LM identification: one home for every model's first guess.

Each is a cheap closed-form estimate that is usually a few LM steps from the optimum; none is a
result.  A model's record names its own (``Model.start``, :mod:`soilstats.models`); the
paper's identification (:mod:`soilstats.identification.sinkage`, ``.shear``) and the
extended models of discovery ask the record, so that both start from the same place.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ModelError
from .registry import get_model
from .wong import wong_start

__all__ = [
    "bekker_start",
    "bernstein_start",
    "janosi_start",
    "reece_from_bekker",
    "reece_start",
    "shear_curve_start",
    "sinkage_start",
]


def sinkage_start(model: str, b: np.ndarray | None, z: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The starting values of a registered sinkage model (its record's ``start``).

    b, z [m] (b may be None for a model without a plate size), p [Pa].  An unknown name, or
    a model of another kind, is a :class:`~soilstats.errors.ModelError`.
    """
    spec = get_model(model, "sinkage")
    if spec.start is None:
        raise ModelError(f"model {spec.name!r} states no starting values (Model.start)")
    data = {"z_m": z} if b is None else {"b_m": b, "z_m": z}
    return spec.start(spec.x_from(data), p)


def bekker_start(b: ArrayLike, z: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Wong's linearised estimate (Fig. 3) of Bekker's (kc, kφ, n).

    b, z [m], p [Pa].  Where Wong's method is undefined (one plate size, no positive p) the
    start falls back to kc = 0, kφ = median(p/z), n = 1.
    """
    try:
        return wong_start(b, z, p)
    except (ValueError, np.linalg.LinAlgError):
        return np.array([0.0, np.median(p / np.maximum(z, 1e-9)), 1.0])


def bernstein_start(z: ArrayLike, p: ArrayLike) -> np.ndarray:
    """Wong's linearised estimate (Fig. 3) of Bernstein's (k, n); z [m], p [Pa]."""
    return wong_start(None, z, p)


def reece_start(b: ArrayLike, z: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Reece's (k1, k2, n) mapped from Bekker's start (:func:`reece_from_bekker`)."""
    return reece_from_bekker(bekker_start(b, z, p), b)


def reece_from_bekker(theta: Sequence[float] | np.ndarray, b: ArrayLike) -> np.ndarray:
    """(k1, k2, n) of Reece equal to Bekker's (kc, kφ, n) at the geometric-mean plate size.

    (k1 + k2·b)(z/b)^n equals (kc/b + kφ)·z^n when k1 = kc·b^(n−1), k2 = kφ·b^(n−1) at the
    reference b [m]; exact for one plate size, a good start for several.
    """
    kc, kphi, n = theta
    b_ref = float(np.exp(np.mean(np.log(np.unique(np.asarray(b, float))))))
    return np.array([kc * b_ref ** (n - 1), kphi * b_ref ** (n - 1), n])


def janosi_start(sigma: ArrayLike, j: ArrayLike, tau: ArrayLike) -> np.ndarray:
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


def shear_curve_start(j: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """(τ_max [Pa], K [m]) of Eq. 13 at one normal pressure, from one test's record.

    The plateau from the top decile, K from where τ first reaches 63 % of it (1 − 1/e).
    """
    tau_top = float(np.median(np.sort(tau)[-max(3, tau.size // 10) :]))
    reach = np.flatnonzero(tau >= 0.632 * tau_top)
    k0 = float(j[reach[0]]) if reach.size and j[reach[0]] > 0 else float(np.ptp(j)) / 20 or 1e-3
    return np.array([tau_top, k0])
