"""The population model's data: every test reduced to its own two-parameter fit.

Test t of a sinkage campaign is reduced to its own weighted Bernstein fit (k̂_t, n̂_t) (Eq. 8,
weights 1/max p as Eq. 9), a shear test to Eq. 13 at its one normal pressure (τ̂_max,t, K̂_t)
(weights 1/max τ), each with its Eq. 4 covariance, and written in the coordinates η_t where
that fit is close to normal (:func:`to_eta`).  :mod:`soilstats.bayes.population_model`
marginalises the test-level effects over these (module docstring there).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np

from ..identification.per_test import TEST_FIT_ERRORS, fit_bernstein_test, fit_shear_test
from .likelihood import PooledProblem

if TYPE_CHECKING:
    from ..identification.pooling import PooledData
    from ..models.base import Model

__all__ = ["PerTestFits", "reference_sinkage", "shear_tests", "sinkage_tests", "to_eta"]


@dataclass(frozen=True)
class PerTestFits:
    """Every usable test reduced to its own two-parameter fit (the population model's data)."""

    params: np.ndarray  # (T, 2) per-test fit: (k, n) or (tau_max, K)
    cov: np.ndarray  # (T, 2, 2) their Eq. 4 covariances
    design: np.ndarray  # (T, m) a_t, the row multiplying the linear moduli
    covariate: np.ndarray  # (T,) b_t [m] or σ_t [Pa]
    test_ids: list
    failed: list


def _reduce_tests(test_ids, test_index, fit_one, covariate_of):
    """Every test reduced to its own two-parameter fit: ``fit_one(mask, tid)`` fits the
    samples of one test, ``covariate_of(mask)`` gives its b or σ.  A test whose fit fails, or
    gives a non-positive parameter or a non-finite covariance, is left out and named."""
    params, covs, covariate, kept, failed = [], [], [], [], []
    for t, tid in enumerate(test_ids.astype(str)):
        m = test_index == t
        try:
            fit = fit_one(m, tid)
        except TEST_FIT_ERRORS:  # reported as left out, as fit_per_test reports it
            failed.append(tid)
            continue
        values, cov = fit.params.to_numpy(), fit.cov.to_numpy()
        if not (np.all(values > 0) and np.all(np.isfinite(cov))):
            failed.append(tid)
            continue
        params.append(values)
        covs.append(cov)
        covariate.append(covariate_of(m))
        kept.append(tid)
    return np.array(params), np.array(covs), np.array(covariate, float), kept, failed


def sinkage_tests(pooled: PooledData, spec: Model) -> PerTestFits:
    """Bernstein fit (Eq. 8) of every test on its own (tests whose fit fails: left out)."""
    z, b, p, w = pooled.x["z_m"], pooled.x["b_m"], pooled.y, pooled.weights
    params, covs, sizes, kept, failed = _reduce_tests(
        pooled.tests["test_id"],
        pooled.test_index,
        lambda m, tid: fit_bernstein_test(z[m], p[m], w[m], name=f"bernstein {tid}"),
        lambda m: b[m][0],
    )
    return PerTestFits(params, covs, _design(spec, sizes), sizes, kept, failed)


def _design(spec: Model, sizes: np.ndarray) -> np.ndarray:
    """(T, q) a_t: the power law's basis (``Model.power_law``) at each test's plate size b_t,
    so that k_t = a_tᵀ(moduli): (1/b_t, 1) for Bekker, 1 for Bernstein."""
    power_law = cast(Callable, spec.power_law)  # a population layout: a power law
    basis, _ = power_law(spec.x_from({"b_m": sizes, "z_m": np.ones_like(sizes)}))
    return np.column_stack([np.broadcast_to(np.asarray(g, float), sizes.shape) for g in basis])


def shear_tests(problem: PooledProblem) -> PerTestFits:
    """Eq. 13 at one normal pressure fitted to every test on its own (failures left out)."""
    sigma, j = problem.x
    params, covs, sigmas, kept, failed = _reduce_tests(
        problem.tests["test_id"],
        problem.test_index,
        lambda m, tid: fit_shear_test(j[m], problem.y[m], problem.w[m], name=f"shear {tid}"),
        lambda m: float(np.mean(sigma[m])),
    )
    design = np.column_stack([np.ones_like(sigmas), sigmas])
    return PerTestFits(params, covs, design, sigmas, kept, failed)


def reference_sinkage(kn: np.ndarray, cov: np.ndarray) -> float:
    """ln z_ref: the median over tests of the value decorrelating ln k̂_t and n̂_t."""
    return float(np.median(-cov[:, 0, 1] / kn[:, 0] / cov[:, 1, 1]))


def scatter_sinkage(fits: PerTestFits, z: np.ndarray, ln_zref: float) -> float:
    """ln z_s, the sinkage [m] at which the population model places its preparation scatter:
    where the tests' own curves scatter least, i.e. where ln p̂_t(z) and n̂_t are uncorrelated
    over tests (ln z_s = −Cov(ln k̂, n̂)/Var(n̂), within groups of one plate width, so Eq. 7's
    plate effect is not read as scatter), kept inside the measured sinkages ``z`` [m] (their
    5–95 % range).  Without a spread of n̂ to locate it, ``ln_zref``, clipped alike.

    Why it matters (docs/posterior.md, "Where the scatter sits"): the Beta(2, 2) prior on the
    correlation of the level and exponent scatter favours independence at this sinkage.
    """
    lo, hi = np.log(np.quantile(z[z > 0], [0.05, 0.95]))
    ln_k, n = np.log(fits.params[:, 0]), fits.params[:, 1]
    _, group = np.unique(fits.covariate, return_inverse=True)
    counts = np.bincount(group)
    within = counts[group] > 1
    if np.count_nonzero(within) - np.count_nonzero(counts > 1) >= 2:
        dk = ln_k - (np.bincount(group, ln_k) / counts)[group]
        dn = n - (np.bincount(group, n) / counts)[group]
        var_n = float(np.sum(dn[within] ** 2))
        if var_n > 0:
            return float(np.clip(-np.sum(dk[within] * dn[within]) / var_n, lo, hi))
    return float(np.clip(ln_zref, lo, hi))


def to_eta(
    params: np.ndarray, cov: np.ndarray, ln_zref: float, log_second: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Per-test fits and covariances → η = (ln a + g·ln z_ref, g), g = b or ln b, and the
    delta-method covariances of η."""
    g = np.log(params[:, 1]) if log_second else params[:, 1]
    dg = 1.0 / params[:, 1] if log_second else np.ones(len(params))
    eta = np.column_stack([np.log(params[:, 0]) + g * ln_zref, g])
    jac = np.zeros_like(cov)
    jac[:, 0, 0] = 1.0 / params[:, 0]
    jac[:, 0, 1] = ln_zref * dg
    jac[:, 1, 1] = dg
    return eta, jac @ cov @ np.swapaxes(jac, 1, 2)
