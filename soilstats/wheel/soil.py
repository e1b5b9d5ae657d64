"""The soil a wheel validation predicts from: plate tests only, as posterior draws.

:func:`plate_draws` identifies the pressure–sinkage law on the campaign's plate tests and
returns joint draws of its parameters.  By default (``kind="auto"``) these are **population
draws** (:func:`soilstats.bayes.sample_population`: a *new* preparation, parameter
uncertainty plus test-to-test scatter — a wheel run is a new preparation of the sand), and
**pooled posterior draws** (:func:`soilstats.bayes.sample_posterior`: parameter uncertainty
only) where the plates cannot support a population: fewer than three tests, a model without
a population layout, a least-squares start flagged ``plate-exponents`` (plates that disagree
on n would be read as scatter between preparations, docs/posterior.md), or a population
sampler that did not converge.  The reason is recorded either way.  No wheel run is used.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..errors import InputError, SoilstatsError
from ..models import get_model

if TYPE_CHECKING:
    from ..bayes.result import PosteriorResult
    from ..campaign.campaign import Campaign
    from ..models.base import Model

__all__ = ["PlateDraws", "choose_law", "plate_draws", "soil_tests"]

KINDS = ("auto", "population", "pooled")


@dataclass(frozen=True, eq=False)
class PlateDraws:
    """Joint draws of the soil's pressure–sinkage parameters, from plate tests only.

    ``kind`` is ``"population"`` or ``"pooled"``; ``reason`` says why; ``posterior`` is the
    :class:`~soilstats.bayes.PosteriorResult` they came from; ``params`` summarises the
    soil-level estimates (posterior mean, sd and 90 % interval of each sampled quantity).
    """

    draws: pd.DataFrame = field(repr=False)
    kind: str
    reason: str
    law: str
    soil: str
    n_tests: int
    plate_sizes_m: tuple[float, ...]
    posterior: PosteriorResult | None = field(repr=False)  # None: draws given as a table
    params: dict

    @property
    def label(self) -> str:
        """How the draws are named in a prediction's parameter sources."""
        return (
            "population draws (a new preparation) from the plate tests"
            if self.kind == "population"
            else "pooled posterior draws (one parameter set) from the plate tests"
        )

    def to_dict(self) -> dict:
        return {
            "kind": self.kind,
            "reason": self.reason,
            "law": self.law,
            "soil": self.soil,
            "plate_tests": self.n_tests,
            "plate_sizes_m": list(self.plate_sizes_m),
            "n_draws": len(self.draws),
            "converged": bool(getattr(self.posterior, "converged", True)),
            "estimates": self.params,
        }


def soil_tests(campaign: Campaign, soil: str | None) -> tuple[str, pd.DataFrame]:
    """The soil whose plate tests are used (the only one, or the one named) and its tests."""
    tests = campaign.tests
    sinkage = tests[tests["kind"] == "sinkage"]
    soils = sorted(sinkage["soil"].astype(str).unique())
    if not soils:
        raise SoilstatsError("the campaign has no sinkage (plate) tests to identify the soil from")
    if soil is None:
        if len(soils) > 1:
            raise InputError(f"the campaign has several soils {soils}: choose one with --soil")
        soil = soils[0]
    if soil not in soils:
        raise InputError(f"no plate tests of soil {soil!r}; the campaign has {soils}")
    return soil, sinkage[sinkage["soil"].astype(str) == soil]


def choose_law(tests: pd.DataFrame, law: str | None = None) -> str:
    """``law`` if given, else Bekker with two or more plate sizes, Bernstein with one."""
    if law is not None:
        get_model(law, kind="sinkage")
        return law
    sizes = tests["b_m"].dropna().round(9).nunique()
    return "bekker" if sizes >= get_model("bekker").min_plate_sizes else "bernstein"


def _estimates(post: PosteriorResult) -> dict:
    table = post.summary_table(0.9)
    out = {}
    for name, row in table.iterrows():
        lo, hi = table.columns[2], table.columns[3]
        out[str(name)] = {
            "mean": float(row["mean"]),
            "sd": float(row["sd"]),
            "q05": float(row[lo]),
            "q95": float(row[hi]),
        }
    return out


def plate_draws(
    campaign: Campaign,
    *,
    soil: str | None = None,
    law: str | None = None,
    kind: str = "auto",
    n_draws: int = 2000,
    seed: int = 0,
    progress: bool = False,
) -> PlateDraws:
    """Identify the soil on the plate tests and return ``n_draws`` joint draws (module doc).

    ``kind`` is ``"auto"`` (population where the plates support it, else pooled),
    ``"population"`` (an error where they do not) or ``"pooled"``.
    """
    from ..bayes import sample_population, sample_posterior  # deferred: arviz (sampling loads it)

    if kind not in KINDS:
        raise InputError(f"draws kind must be one of {KINDS}, got {kind!r}")
    soil, tests = soil_tests(campaign, soil)
    law = choose_law(tests, law)
    sizes = tuple(float(b) for b in sorted(tests["b_m"].dropna().round(9).unique()))
    seeds = np.random.SeedSequence([int(seed), 0x5701]).generate_state(2, np.uint32)
    reason = "asked for (--draws pooled)" if kind == "pooled" else ""
    post = None
    if kind != "pooled":
        why_not = _population_blocker(tests, law, get_model(law))
        if why_not is None:
            try:
                post = sample_population(
                    campaign, law, seed=int(seeds[0]), progress=progress, soil=soil
                )
            except (SoilstatsError, ValueError) as err:
                why_not = f"the population model could not be sampled ({err})"
        if post is not None and not post.converged:
            failed = "; ".join(f.message for f in post.flags)
            why_not = f"the population sampler did not converge ({failed})"
        if post is not None and why_not is None:
            flagged = {f["code"] for f in post.least_squares_health()}
            if "plate-exponents" in flagged:
                why_not = (
                    "the least-squares start is flagged plate-exponents: the plates disagree on "
                    "n, which a population would read as scatter between preparations"
                )
        if why_not is not None:
            if kind == "population":
                raise SoilstatsError(f"population draws refused: {why_not}")
            post, reason = None, f"pooled because {why_not}"
        else:
            reason = (
                f"population: {len(tests)} plate tests support a new-preparation model "
                "(parameter uncertainty plus test-to-test scatter), as a wheel run is a new "
                "preparation of the sand"
            )
    if post is None:
        try:
            post = sample_posterior(campaign, law, seed=int(seeds[0]), progress=progress, soil=soil)
        except (SoilstatsError, ValueError) as err:
            raise SoilstatsError(
                f"the {law} posterior of the plate tests of {soil!r} cannot be sampled: {err}. "
                "For the wheel, choose another law (--law bernstein) or fewer tests (--select)"
            ) from None
    draws = post.draws(n_draws, seed=int(seeds[1]))
    return PlateDraws(
        draws=draws.reset_index(drop=True),
        kind=post.kind,
        reason=reason,
        law=law,
        soil=soil,
        n_tests=len(tests),
        plate_sizes_m=sizes,
        posterior=post,
        params=_estimates(post),
    )


def _population_blocker(tests: pd.DataFrame, law: str, spec: Model) -> str | None:
    if spec.population is None:
        return f"the {law} model has no population layout"
    if len(tests) < 3:
        return f"only {len(tests)} plate tests (a population needs at least 3)"
    return None
