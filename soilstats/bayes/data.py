"""From a campaign to a :class:`PooledProblem`: the same data and weights as the LS fit."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..fitting.result import FitResult
from ..identification import fit_shear, fit_sinkage, pool_sinkage
from ..identification.pooling import pool_shear
from ..models import BERNSTEIN, MOHR_COULOMB, get_model
from .likelihood import PooledProblem
from .priors import resolve_priors

__all__ = ["SHEAR_MODELS", "SINKAGE_MODELS", "pooled_problem"]

SINKAGE_MODELS = ("bekker", "bernstein", "reece")
SHEAR_MODELS = ("mohr-coulomb", "janosi")


def pooled_problem(
    campaign,
    model: str,
    *,
    priors: Mapping[str, object] | None = None,
    points_per_test: int | None = 100,
    **selection,
) -> tuple[PooledProblem, FitResult]:
    """The pooled data of ``model`` and its least-squares fit (the sampler's starting point).

    Sinkage models use :func:`soilstats.identification.pool_sinkage` (z > 0, up to
    ``points_per_test`` equidistant samples, w = 1/max p per test); shear models use the data
    of :func:`soilstats.identification.fit_shear` (Mohr–Coulomb: steady-state parts, unit
    weights; Janosi: whole records with j ≥ 0, w = 1/max τ per test).

    Returns
    -------
    (PooledProblem, FitResult)
    """
    spec = get_model(model)
    if spec.name in SINKAGE_MODELS:
        fit = fit_sinkage(campaign, spec.name, points_per_test=points_per_test, **selection)
        pooled = pool_sinkage(campaign, points_per_test=points_per_test, **selection)
        b, z = pooled.x["b_m"], pooled.x["z_m"]
        x = z if spec is BERNSTEIN else np.vstack([b, z])
        problem = PooledProblem(
            model=spec,
            x=x,
            y=pooled.y,
            w=pooled.weights,
            test_index=pooled.test_index,
            tests=pooled.tests,
            priors=resolve_priors(spec.name, spec.param_names, priors),
            plate_sizes=np.unique(b),
            inputs={k: np.asarray(v, float) for k, v in pooled.x.items()},
        )
        return problem, fit
    if spec.name in SHEAR_MODELS:
        fit = fit_shear(campaign, spec.name, **selection)
        weighting = "none" if spec is MOHR_COULOMB else "max-stress"
        pooled = pool_shear(
            campaign, steady_only=spec is MOHR_COULOMB, weighting=weighting, **selection
        )
        sigma, j = pooled.x["sigma_Pa"], pooled.x["j_m"]
        # Tests that contribute no sample (never steady) are not units of the posterior.
        used = pooled.tests["used"].to_numpy() > 0
        owner = np.cumsum(used)[pooled.test_index] - 1
        x = sigma if spec is MOHR_COULOMB else np.vstack([sigma, j])
        problem = PooledProblem(
            model=spec,
            x=x,
            y=pooled.y,
            w=pooled.weights,
            test_index=owner,
            tests=pooled.tests[used].reset_index(drop=True),
            priors=resolve_priors(spec.name, spec.param_names, priors),
            inputs={k: np.asarray(v, float) for k, v in pooled.x.items()},
        )
        return problem, fit
    raise ValueError(
        f"no posterior for model {spec.name!r}; choose one of {SINKAGE_MODELS + SHEAR_MODELS}"
    )
