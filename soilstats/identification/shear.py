"""``fit_shear``: shear parameters from shear-ring tests (Section 2.2, Eqs. 12–15)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Literal, cast

import numpy as np

from ..errors import CampaignError, ModelError
from ..fitting.identify import identify
from ..fitting.linear import linear_least_squares
from ..fitting.result import FitResult, HealthFlag
from ..models import Model, get_model
from ..quality import screened
from .bootstrap import test_bootstrap
from .pooling import pool_shear
from .result import CampaignFit
from .reuse import reusable

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..campaign.tables import Criterion

__all__ = ["fit_shear", "pool_shear"]

DEG_PER_RAD = 180.0 / np.pi


@reusable
def fit_shear(
    campaign: Campaign,
    model: str | Model = "mohr-coulomb",
    *,
    weighting: Literal["none", "max-stress"] | None = None,
    p0: Sequence[float] | np.ndarray | None = None,
    on_failure: Literal["raise", "warn"] = "raise",
    test_resamples: int | Literal["auto"] = "auto",
    seed: int = 0,
    quality: Literal["off", "flag", "clean"] = "clean",
    **selection: Criterion,
) -> CampaignFit:
    """Identify c, φ (Mohr–Coulomb, Eq. 15) or c, φ, K (Janosi–Hanamoto, Eq. 13).

    Mohr–Coulomb is a *linear* least-squares fit of τ = c + σ·tan φ on the steady-state part
    of every test (rule in :mod:`soilstats.identification.steady_state`); φ and its σ follow
    from tan φ by the delta method.  Janosi–Hanamoto is the weighted LM fit of Eq. 13 on
    whole records (j ≥ 0).  Weighting defaults to unit weights for Mohr–Coulomb (as the
    paper's Section 4.2) and 1/max(τ) per test for Janosi (Section 2.2 → 2.1).  ``model``
    may be any registered shear model (:func:`soilstats.register_model`): its record says
    whether it fits the steady-state parts (``Model.steady_state``, solved in closed form
    through ``Model.linear_form``) or whole records (weighted LM from ``Model.start``), and
    its default weighting.
    ``test_resamples`` and ``seed`` run the cluster bootstrap over tests that gives the
    test-level ``stderr`` of a fit on five tests or more, as in :func:`fit_sinkage`;
    ``quality`` as there.
    """
    spec = get_model(model, "shear")
    if weighting is None:
        weighting = cast(Literal["none", "max-stress"], spec.weighting or "max-stress")
    campaign = screened(campaign, quality)
    pooled = pool_shear(campaign, steady_only=spec.steady_state, weighting=weighting, **selection)
    sigma, tau, w = pooled.x["sigma_Pa"], pooled.y, pooled.weights
    groups = pooled.tests
    n_tests = len(groups)
    notes = [
        f"{n_tests} shear tests; normal pressures "
        f"{groups['sigma_mean_Pa'].min():.4g}–{groups['sigma_mean_Pa'].max():.4g} Pa."
    ]
    flags = []
    if spec.steady_state:
        unsteady = groups[~groups["steady"].astype(bool)]
        notes.append(
            "Steady-state part per test: from where tau stays >= 98% of its plateau "
            "(median of the last 25% of j); used only if it drifts <= 10%."
        )
        if len(unsteady):
            msg = (
                f"{len(unsteady)} test(s) never reached a steady state and were not used: "
                + "; ".join(f"{r.test_id}: {r.reason}" for r in unsteady.itertuples())
            )
            notes.append(msg)
            flags.append(HealthFlag("excluded-tests", msg))
        if (
            np.unique(np.round(groups.loc[groups["steady"].astype(bool), "sigma_mean_Pa"], 6)).size
            < 2
        ):
            raise CampaignError(
                "Mohr–Coulomb needs steady-state data at two or more normal "
                "pressures (Section 2.2)",
                file=campaign.file_name("shear"),
                column="normal_force_N",
            )
        lin = linear_least_squares(
            np.column_stack([np.ones_like(sigma), sigma]), tau, weights=w, names=("c", "tan_phi")
        )
        c, t = lin.params.to_numpy()
        grad = np.array([[1.0, 0.0], [0.0, DEG_PER_RAD / (1.0 + t * t)]])  # d(c, φ°)/d(c, tan φ)
        cov = grad @ lin.cov.to_numpy() @ grad.T
        notes.append(
            "Linear least squares (Section 2.2); phi = atan(tan phi), sigma by the delta method."
        )
        mohr_coulomb = FitResult.closed_form(
            spec,
            [c, np.degrees(np.arctan(t))],
            cov,
            w * lin.residuals,
            w * tau,
            method="linear least squares on the steady-state part (Eq. 15)",
            message="linear least squares (closed form)",
            condition_number=lin.condition_number,
            x=sigma,
            y=tau,
        )
        bootstrap = test_bootstrap(spec, sigma, pooled, mohr_coulomb, test_resamples, seed, notes)
        return CampaignFit.of(mohr_coulomb, pooled, notes, flags, bootstrap, campaign)
    x = spec.x_from(pooled.x)
    if p0 is None:
        if spec.start is None:
            raise ModelError(f"model {spec.name!r} states no starting values: pass p0")
        p0 = spec.start(x, tau)
    notes.append("Weights " + ("1/max(tau) per test." if weighting == "max-stress" else "1."))
    result = identify(spec, x, tau, p0, weights=w, on_failure=on_failure)
    bootstrap = test_bootstrap(spec, x, pooled, result, test_resamples, seed, notes)
    return CampaignFit.of(result, pooled, notes, flags, bootstrap, campaign)
