"""Whether posterior draws are fit for a rover Monte Carlo: one decision, in the library.

:func:`hand_out` takes the posteriors of one soil (a sinkage model, and a shear model drawn
independently beside it: :func:`~soilstats.bayes.joint_draws`), draws the rows a Monte Carlo
would get, and decides whether they may be handed out:

* every posterior converged (R-hat ≤ 1.01, bulk and tail ESS ≥ 400);
* at most :data:`~soilstats.bayes.support.MAX_OUTSIDE` of the draws leave the physical
  support (:func:`~soilstats.bayes.support.check_support`); those that do are never handed out;
* for a *population* posterior, the least-squares fit it starts from is not flagged
  ``plate-exponents``: the population's scatter would take up the model's misfit between
  plate sizes as scatter between preparations (GRC-1's Bekker: a stiffness sd of 5.8×).

What can be known before sampling is known before: :func:`preflight` runs the least-squares
fit alone and gives the refusals it implies, in well under a second, so that no sampling is
spent on draws that would be refused. The command line (``soilstats posterior``) only prints
the decision and writes what it allows; a Python caller gets the same answer from
:func:`hand_out` or :meth:`PosteriorResult.handout`.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import pandas as pd

from ..identification import fit_shear, fit_sinkage
from ..identification.conditions import model_for
from ..models import get_model
from .joint import PosteriorDraws, joint_draws
from .support import SupportCheck, check_support, negative_modulus_width

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..campaign.tables import Criterion
    from ..fitting.result import HealthFlag

__all__ = ["Handout", "hand_out", "lsq_refusals", "preflight"]

#: Least-squares health codes that refuse a *population* posterior: the population's scatter
#: would be the model's misfit (module docstring). Other flags stay warnings.
POPULATION_REFUSALS = ("plate-exponents",)


class HandedPosterior(PosteriorDraws, Protocol):
    """What :func:`hand_out` reads of a posterior (:class:`~.result.PosteriorResult`, which
    reaches this module through :meth:`~.result.PosteriorResult.handout`: an import of it
    here would close a loop, tests/test_layers.py)."""

    @property
    def idata(self) -> Any: ...  # arviz.InferenceData (Any: see PosteriorResult.idata)

    @property
    def model_name(self) -> str: ...

    @property
    def kind(self) -> str: ...

    @property
    def flags(self) -> tuple[HealthFlag, ...]: ...

    @property
    def converged(self) -> bool: ...

    def least_squares_health(self) -> list[dict]: ...


@dataclass(frozen=True)
class Handout:
    """The draws a rover Monte Carlo may be given, and why (or why not).

    Attributes
    ----------
    draws : DataFrame
        Joint draws inside the physical support, rows in random order (SI units, φ in
        degrees): what ``draws.csv`` holds.
    support : SupportCheck
        Which of all draws were physical, and why the others were not.
    failures : tuple of str
        Every reason the draws are not fit for a Monte Carlo (empty: they are).
    least_squares_health : dict
        Model → the health flags (``code``, ``message``) of its least-squares start: its
        data and model problems hold for the posterior too (warnings unless refusing).
    n_drawn : int
        Rows drawn before the support check.
    """

    draws: pd.DataFrame
    support: SupportCheck
    failures: tuple[str, ...]
    least_squares_health: dict = field(default_factory=dict)
    n_drawn: int = 0

    @property
    def passed(self) -> bool:
        """True when the draws may be handed out (no failure)."""
        return not self.failures

    @property
    def negative_modulus_below_m(self) -> float | None:
        """Where kc < 0 in the draws: the contact width [m] below which Bekker's modulus
        kc/b + kφ turns negative in 1 % of them (None when it never does)."""
        return negative_modulus_width(self.draws)

    def to_dict(self) -> dict:
        return {
            "passed": self.passed,
            "failures": list(self.failures),
            "draws_written": len(self.draws),
            "draws_drawn": self.n_drawn,
            "support": self.support.to_dict(),
            "negative_modulus_below_m": self.negative_modulus_below_m,
            "least_squares_health": self.least_squares_health,
        }


def lsq_refusals(health: dict, population: bool) -> list[str]:
    """The refusals a least-squares start implies (model → its flags, ``code``/``message``):
    for a population, :data:`POPULATION_REFUSALS`."""
    if not population:
        return []
    return [
        f"{model}: its least-squares fit is flagged plate-exponents, so the population's "
        "scatter would take up the model's misfit between plate sizes as scatter between "
        f"preparations ({f['message']})"
        for model, flags in health.items()
        for f in flags
        if f["code"] in POPULATION_REFUSALS
    ]


def preflight(
    campaign: Campaign,
    models: Iterable[str],
    *,
    population: bool,
    **selection: Criterion,
) -> tuple[list[str], dict]:
    """What refuses the draws before any sampling: (failures, least-squares health by model).

    Runs each model's least-squares fit alone (milliseconds) on the selection the posterior
    will use; a fit that cannot be made at all raises its own error here, as sampling would.
    """
    health, unidentifiable = {}, []
    for name in models:
        spec = get_model(name)
        # The very fit the sampler starts from (the same defaults: bayes.data, .population).
        fitter = fit_sinkage if spec.kind == "sinkage" else fit_shear
        fit = fitter(campaign, spec, test_resamples=0, **selection)
        health[name] = [{"code": f.code, "message": f.message} for f in fit.flags]
        # identify's decision (plates closer than 1.5x cannot separate kc/b from kphi): the
        # posterior of such a design is its prior's shape along the ridge, not the soil's.
        tests = fit.tests
        assert tests is not None  # a fit_sinkage/fit_shear result always carries its tests
        kept, why = model_for(spec.kind, name, None, tests)
        if kept is None:
            unidentifiable.append(
                f"{name}: {why} (identify would not fit it); sample --model bernstein per "
                "plate size instead, or add tests with plates further apart"
            )
    return unidentifiable + lsq_refusals(health, population), health


def hand_out(
    results: Iterable[HandedPosterior],
    contact_widths: tuple[float, float],
    *,
    seed: int | None = 0,
    population: bool | None = None,
) -> Handout:
    """Draw the rows a Monte Carlo would get from ``results`` (one posterior, or a sinkage
    and a shear posterior of one soil), check them, and decide (module docstring).

    ``contact_widths`` (b_min, b_max) [m]: the contact widths the draws will be used at (the
    plate modulus must be positive over them). ``population``: whether these are population
    posteriors (default: from the results' kind).
    """
    results = list(results)
    if population is None:
        population = any(r.kind == "population" for r in results)
    n = min(r.idata.posterior.sizes["chain"] * r.idata.posterior.sizes["draw"] for r in results)
    draws = (
        joint_draws(results[0], results[1], n, seed=seed, allow_unconverged=True)
        if len(results) == 2
        else results[0].draws(n, seed=seed, allow_unconverged=True)
    )
    models = [r.model_name for r in results]
    support = check_support(draws, contact_widths, models)
    failures = [
        f"{r.model_name} {r.kind}: not converged ({'; '.join(f.message for f in r.flags)})"
        for r in results
        if not r.converged
    ]
    if not support.passed:
        failures.append(support.describe())
    health = {r.model_name: r.least_squares_health() for r in results}
    failures += lsq_refusals(health, population)
    kept = draws[support.inside].reset_index(drop=True)
    return Handout(kept, support, tuple(failures), health, len(draws))
