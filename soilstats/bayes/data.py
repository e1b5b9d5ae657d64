"""From a campaign to a :class:`PooledProblem`: the same data and weights as the LS fit."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ModelError
from ..fitting.result import FitResult
from ..identification import fit_shear, fit_sinkage, pool_sinkage
from ..identification.adequacy import outside_own_range, test_forms
from ..identification.pooling import pool_shear
from ..models import get_model, model_names
from .likelihood import PooledProblem
from .priors import resolve_priors

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..campaign.tables import Criterion
    from ..models import Model

__all__ = ["pooled_problem"]


def pooled_problem(
    campaign: Campaign,
    model: str | Model,
    *,
    priors: Mapping[str, object] | None = None,
    points_per_test: int | None = 100,
    **selection: Criterion,
) -> tuple[PooledProblem, FitResult]:
    """The pooled data of ``model`` and its least-squares fit (the sampler's starting point).

    Sinkage models use :func:`soilstats.identification.pool_sinkage` (z > 0, up to
    ``points_per_test`` equidistant samples, w = 1/max p per test); shear models use the data
    of :func:`soilstats.identification.fit_shear` (Mohr–Coulomb: steady-state parts, unit
    weights; Janosi: whole records with j ≥ 0, w = 1/max τ per test).  Which, and the
    inputs ``x``, the model's record says (``kind``, ``steady_state``, ``weighting``,
    ``columns``).

    Returns
    -------
    (PooledProblem, FitResult)
    """
    spec = get_model(model)
    if spec.kind == "sinkage":
        fit = fit_sinkage(
            campaign, spec, points_per_test=points_per_test, test_resamples=0, **selection
        )
        pooled = pool_sinkage(campaign, points_per_test=points_per_test, **selection)
        problem = PooledProblem(
            model=spec,
            x=spec.x_from(pooled.x),
            y=pooled.y,
            w=pooled.weights,
            test_index=pooled.test_index,
            tests=pooled.tests,
            priors=resolve_priors(spec, spec.param_names, priors),
            plate_sizes=np.unique(pooled.x["b_m"]),
            inputs={k: np.asarray(v, float) for k, v in pooled.x.items()},
        )
        return problem, _with_aggregation_bias(fit, problem)
    if spec.kind == "shear":
        fit = fit_shear(campaign, spec, test_resamples=0, **selection)
        pooled = pool_shear(
            campaign,
            steady_only=spec.steady_state,
            weighting=spec.weighting or "max-stress",
            **selection,
        )
        # Tests that contribute no sample (never steady) are not units of the posterior.
        used = pooled.tests["used"].to_numpy() > 0
        owner = np.cumsum(used)[pooled.test_index] - 1
        problem = PooledProblem(
            model=spec,
            x=spec.x_from(pooled.x),
            y=pooled.y,
            w=pooled.weights,
            test_index=owner,
            tests=pooled.tests[used].reset_index(drop=True),
            priors=resolve_priors(spec, spec.param_names, priors),
            inputs={k: np.asarray(v, float) for k, v in pooled.x.items()},
        )
        return problem, _with_aggregation_bias(fit, problem)
    raise ModelError(
        f"no posterior for model {spec.name!r} (a {spec.kind or 'non-soil'} model); choose "
        f"one of {model_names('sinkage') + model_names('shear')}"
    )


def _with_aggregation_bias(fit: FitResult, problem: PooledProblem) -> FitResult:
    """``fit`` with an ``aggregation-bias`` flag where its pooled n lies outside the range
    of every test's own n (:func:`~soilstats.identification.adequacy.outside_own_range`):
    the posterior starts from it and reports its flags (``least_squares_health``), which
    its fit without the test bootstrap would not raise."""
    if "n" not in fit.params.index or any(f.code == "aggregation-bias" for f in fit.flags):
        return fit
    forms = test_forms(problem.inputs["z_m"], problem.y, problem.test_index)
    flag = outside_own_range(forms.n, float(fit.params["n"]))
    return fit if flag is None else fit.annotated(flags=[flag])
