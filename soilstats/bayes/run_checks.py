"""What a posterior run asks for, checked before any sampling, and its seeds and widths
(``soilstats posterior``'s library logic, moved out of cli/, issue #45: commands only parse,
call and print).

Each check refuses with an :class:`~soilstats.errors.InputError` or
:class:`~soilstats.errors.ModelError` naming the option, in the time of a parse, not after
minutes of sampling: the models (:func:`check_models`), the draws asked for
(:func:`check_draws`), a simulator export's parameters and stated inputs
(:func:`check_simulator_request`), the contact widths (:func:`contact_widths`).

This module imports nothing heavy (no pandas, ArviZ or emcee at import): a refusal before
sampling must not pay for them.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from .._budget import check_budget
from ..errors import InputError, ModelError
from ..models import Model, get_model

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign

__all__ = [
    "CONTACT_WIDTH_MAX_M",
    "check_draws",
    "check_models",
    "check_simulator_request",
    "contact_widths",
    "extrapolation_warnings",
    "has_population",
    "model_seed",
    "only_soil",
    "prior_seed",
    "tested_widths",
]

#: Largest contact width --contact-width takes [m]: wider is no wheel or track of a vehicle.
CONTACT_WIDTH_MAX_M = 10.0

#: Bytes per kept draw and column, all copies together: emcee's unthinned chain (thinning
#: τ/2, a few steps), the thinned chain, the InferenceData and the draws table.
_BYTES_PER_DRAW_VALUE = 8 * 8


def _checked_model(name: str) -> Model:
    """The record of one model of ``--model`` (bayes.prior_options.posterior_model)."""
    from .prior_options import posterior_model  # deferred: scipy.stats (the export's SCM plan)

    return posterior_model(name)


def check_models(models: Sequence[str]) -> None:
    """``--model``: one registered model, or a sinkage and a shear model joined by '+'."""
    kinds = [_checked_model(m).kind for m in models]
    if len(models) > 2 or len(set(kinds)) < len(kinds):
        raise ModelError(
            f"--model {'+'.join(models)}: give one model, or one sinkage and one shear model "
            "joined by '+' (e.g. bekker+janosi)"
        )


def model_seed(seed: int, index: int) -> int:
    """The seed of the ``index``-th model of one run: ``seed`` itself for the first, one
    drawn from ``SeedSequence([seed, index])`` for the others.  With one seed for both, the
    sinkage and shear samplers drew the same random streams, and rows of their draws with
    the same index were coupled (Spearman 0.9 between kφ and φ)."""
    if index == 0:
        return int(seed)
    return int(np.random.SeedSequence([int(seed), index]).generate_state(1, np.uint32)[0])


def prior_seed(seed: int, models: Sequence[str]) -> int:
    """The seed of the user priors' draws: one stream of its own after the models'
    (``SeedSequence([seed, len(models)])``), so they are independent of the posterior."""
    return model_seed(seed, len(models))


def has_population(model: str) -> bool:
    """Whether the model's record has a population layout (``Model.population``)."""
    return get_model(model).population is not None


def check_simulator_request(
    simulator: str | None,
    models: Sequence[str],
    stated: dict[str, tuple],
    *,
    elastic_K: float | None,
    damping_R: float | None,
    repair: float | None,
    contact: str | None,
    seed: int,
) -> None:
    """--simulator needs every parameter it writes, from the models, the Bernstein mapping or
    user priors, and valid stated inputs: refuse before sampling, not after."""
    if not simulator:
        if repair is not None:
            raise InputError("--scm-repair repairs a simulator export: give --simulator too")
        if contact:
            raise InputError("--scm-contact checks a simulator export: give --simulator too")
        return
    from .export import (  # deferred: scipy.stats
        REPAIR_MAX,
        missing_message,
        scm_plan,
        stated_inputs,
    )
    from .scm_wheel import contact_patch  # deferred: pandas
    from .stated_priors import sample_priors  # deferred: scipy.stats

    contact_patch(contact)  # LENGTH:WIDTH, positive and finite

    params = [n for m in models for n in _checked_model(m).param_names]
    plan = scm_plan(params, stated)
    sinkage = [m for m in models if _checked_model(m).kind == "sinkage"]
    if sinkage and plan["kphi"] == "missing":
        raise ModelError(
            f"--simulator {simulator} takes Bekker's law p = (kc/b + kphi) z^n; "
            f"{sinkage[0]} ({_checked_model(sinkage[0]).equation}) has no such form: use "
            "--model bekker, or bernstein (mapped as Kphi = k, Kc = 0)"
        )
    missing = [k for k, v in plan.items() if v == "missing"]
    if missing:
        raise InputError(f"--simulator {missing_message(simulator, missing, params)}")
    stated_inputs(elastic_K, damping_R)
    if repair is not None and not 1 < repair <= REPAIR_MAX:
        raise InputError(
            f"--scm-repair takes a multiple in (1, {REPAIR_MAX:g}] (elastic_K = MULTIPLE x "
            f"Bekker_Kphi must exceed Bekker_Kphi), got {repair:g}"
        )
    if stated:  # a prior that cannot be drawn, or leaves the support: say so now
        sample_priors(stated, 10_000, prior_seed(seed, models))


def check_draws(draws: int | None, models: Sequence[str] = (), *, force: bool = False) -> None:
    """--draws below the convergence check's ESS floor: refuse before sampling, not after.

    N draws carry an effective sample size of about N at most, so fewer than
    :data:`~soilstats.bayes.result.ESS_MIN` fail the check and exit 2 after all the
    sampling; with ``force`` the user has accepted unconverged (FORCED) draws.  A number of
    draws that cannot be held in memory (:mod:`soilstats._budget`) is refused even then.
    """
    if draws is not None:
        if draws < 1:
            raise InputError(f"--draws takes a whole number >= 1, got {draws}")
        columns = sum(len(_checked_model(m).param_names) + 2 for m in models) or 4
        check_budget(
            f"--draws {draws}",
            float(draws) * columns * _BYTES_PER_DRAW_VALUE,
            "ask for fewer draws (the default is enough for every summary soilstats writes)",
        )
    if draws is None or force:
        return  # (the sampler modules cost seconds to import: not for a refusal before sampling)
    from .population import POPULATION_DRAWS  # deferred: arviz
    from .posterior import DEFAULT_DRAWS  # deferred: arviz
    from .result import ESS_MIN  # deferred: arviz

    if draws < ESS_MIN:
        raise InputError(
            f"--draws {draws} is below {ESS_MIN}, the effective sample size (bulk and "
            f"tail ESS) per parameter the convergence check needs: {draws} draws can "
            f"carry at most about {draws}. Ask for at least {ESS_MIN} (default "
            f"{DEFAULT_DRAWS}, {POPULATION_DRAWS} with --population), or pass --force to "
            "write unconverged draws anyway"
        )


def tested_widths(campaign: Campaign, soil: str) -> tuple[float, float] | None:
    """Smallest and largest plate dimension b [m] of the soil's sinkage tests, if any."""
    tests = campaign.tests
    b = tests.loc[(tests["kind"] == "sinkage") & (tests["soil"].astype(str) == soil), "b_m"]
    b = b.dropna()
    return (float(b.min()), float(b.max())) if len(b) else None


def contact_widths(text: str | None, campaign: Campaign, soil: str) -> tuple[float, float]:
    """``--contact-width B_MIN[:B_MAX]`` [m], or the soil's tested plate widths (1 m when it
    has no sinkage test): the widths every draw must give a positive modulus over."""
    if text:
        lo, _, hi = text.partition(":")
        try:
            widths = (float(lo), float(hi or lo))
        except ValueError:
            raise InputError(
                f"--contact-width takes B_MIN[:B_MAX] in metres, got {text!r}"
            ) from None
        if not 0 < widths[0] <= widths[1] <= CONTACT_WIDTH_MAX_M:
            raise InputError(
                f"--contact-width needs 0 < B_MIN <= B_MAX <= {CONTACT_WIDTH_MAX_M:g} m "
                f"(finite), got {text!r}"
            )
        return widths
    return tested_widths(campaign, soil) or (1.0, 1.0)


def extrapolation_warnings(
    widths: tuple[float, float], tested: tuple[float, float] | None, models: Iterable[str]
) -> list[str]:
    """Say when --contact-width leaves the tested plate sizes for a model whose modulus
    depends on b (Bekker kc/b + kφ, Reece k1 + k2·b): there it is extrapolated, and the
    support check only says it stays positive, not that it is right."""
    # The model's own inputs say whether it depends on the plate width b.
    sized = [f"{m} ({spec.equation})" for m in models if "b [m]" in (spec := get_model(m)).inputs]
    if not sized or tested is None or (tested[0] <= widths[0] and widths[1] <= tested[1]):
        return []
    return [
        f"--contact-width {widths[0]:g}–{widths[1]:g} m leaves the plate sizes tested "
        f"(b = {tested[0]:g}–{tested[1]:g} m): {', '.join(sized)} is extrapolated there, "
        "unconstrained by the data; the support check only says it stays positive"
    ]


def only_soil(campaign: Campaign, soil: str | None) -> str:
    """``soil`` as given, or the campaign's only soil when it was left out (an
    :class:`~soilstats.errors.InputError` listing the soils when there are several)."""
    soils = sorted({str(s) for s in campaign.tests["soil"].dropna()})
    if soil is not None:
        return soil
    if len(soils) == 1:
        return soils[0]
    raise InputError(f"--soil is needed: the campaign has {len(soils)} soils ({', '.join(soils)})")
