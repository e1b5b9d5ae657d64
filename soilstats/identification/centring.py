"""Where a power law's correlations are judged: at the data's centre, not at z = 1 m."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..fitting.result import FitResult

__all__ = ["centred"]


def centred(fit: FitResult, z) -> FitResult:
    """``fit`` with its ``high-correlation`` check judged at the data's centre.

    In p = s·z^n every scale s (k, kc, kφ, k1, k2) is the pressure at z = 1 m, far outside
    any plate test, so s and n are correlated by the parametrisation alone (|corr| > 0.99 for
    an exact power law). Taken at z_ref, the geometric mean sinkage of the data, the scales
    s·z_ref^n are what the data measure; their correlations with n and with each other say
    whether the data separate the parameters.
    """
    names = list(fit.param_names)
    if "n" not in names:
        return fit
    z = np.asarray(z, float)
    log_ref = float(np.mean(np.log(z[z > 0]))) if (z > 0).any() else 0.0
    basis = np.eye(len(names))
    j = names.index("n")
    for i, value in enumerate(fit.values):
        if i != j:
            basis[i, j] = value * log_ref  # d(s z_ref^n)/dn, divided by z_ref^n as the row
    return replace(fit, correlation_basis=basis)
