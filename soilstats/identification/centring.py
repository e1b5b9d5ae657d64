"""Where a power law's correlations are judged: where the data measure it, not at z = 1 m."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike

from ..fitting.result import FitResult

__all__ = ["centred"]


def centred(fit: FitResult, z: ArrayLike) -> FitResult:
    """``fit`` with its ``high-correlation`` check judged where the data measure each scale.

    In p = s·z^n every scale s (k, kc, kφ, k1, k2) is the pressure at z = 1 m, far outside
    any plate test, so s and n are correlated by the parametrisation alone (|corr| > 0.99 for
    an exact power law).  Taken at a reference depth z_s, s·z_s^n is a pressure the data
    measure; at ln z_s = −Cov(s, n)/(s·Var n), from the fit's own covariance (Eq. 4), it is
    uncorrelated with n — the depth the data inform it at, deep in the record (they weigh
    the large pressures) — so what the check then sees is whether the data separate the
    scales from each other (kc from kφ: the plate sizes).  Judged at the geometric-mean
    sinkage instead, a clean power law with n ≈ 1.6 or more (a 0–30 mm record) showed
    |corr(k, n)| > 0.95 and was flagged.  Where the covariance says nothing (σ of n zero or
    not finite) the geometric-mean sinkage of ``z`` is used.
    """
    names = list(fit.param_names)
    if "n" not in names:
        return fit
    j = names.index("n")
    cov = fit.covariance
    var_n = float(cov[j, j])
    fallback = None
    basis = np.eye(len(names))
    for i, value in enumerate(fit.values):
        if i == j:
            continue
        log_ref = -float(cov[i, j]) / (value * var_n) if value and var_n > 0 else math.nan
        if not math.isfinite(log_ref):
            if fallback is None:
                z = np.asarray(z, float)
                fallback = float(np.mean(np.log(z[z > 0]))) if (z > 0).any() else 0.0
            log_ref = fallback
        basis[i, j] = value * log_ref  # d(s z_s^n)/dn, divided by z_s^n as the row
    return replace(fit, correlation_basis=basis)
