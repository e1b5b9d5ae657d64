"""The posterior of every model of a run, sampled here or — the second of two models with
``jobs`` of 2 or more — in a worker process, with the warnings sampling raised (``soilstats
posterior``'s sampling, moved out of cli/, issue #45).

A worker also draws that model's report figures where its draws are, so only SVG travels
back: the caller hands the figure function in (the report is a floor above this one).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..errors import ConvergenceWarning, SoilstatsWarning
from ..parallel import effective_jobs, in_one_worker
from .run_checks import has_population, model_seed

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign

__all__ = [
    "CaughtWarning",
    "SamplingOptions",
    "in_workers",
    "sample_models",
    "sampling_warnings",
]

#: A model's report figures from its result (``soilstats.report.posterior_pdf.model_figures``).
FigureFunction = Callable[[Any], Any]


@dataclass(frozen=True)
class CaughtWarning:
    """A warning raised while sampling (here or in a worker): its class and its text."""

    category: type[Warning]
    message: str


@dataclass(frozen=True)
class SamplingOptions:
    """What every model of one run is sampled with: the run's seed (each model's own is
    :func:`~.run_checks.model_seed`), the kept draws (None: the sampler's default), the
    soil, population draws where the model has them, progress bars."""

    seed: int
    draws: int | None
    soil: str | None
    population: bool
    progress: bool


def sampling_warnings(caught: Sequence[CaughtWarning]) -> list[str]:
    """The warnings sampling raised, as the run reports them: soilstats' own each in its
    words, numerical ones (numpy overflow, invalid values) summed up in one line, not
    hundreds."""
    ours = [str(w.message) for w in caught if issubclass(w.category, SoilstatsWarning)]
    numeric = len(caught) - len(ours)
    if numeric:
        ours.append(
            f"{numeric} numerical warnings (overflow, invalid values) while sampling: the "
            "sampler reached extreme parameter values (an improper or very wide posterior)"
        )
    return ours


def in_workers(models: Sequence[str], jobs: int | None) -> bool:
    """Sample the second of two models in a worker process (``jobs`` of 2 or more); this
    process samples the first."""
    return len(models) == 2 and effective_jobs(jobs) > 1


def sample_models(
    campaign: Campaign,
    models: Sequence[str],
    priors: dict[str, Any],
    options: SamplingOptions,
    *,
    jobs: int | None = 1,
    figures: FigureFunction | None = None,
) -> tuple[list[Any], list[CaughtWarning], dict[str, Any]]:
    """The posterior of every model, the warnings sampling raised, and — where the models
    were sampled in worker processes (``jobs``) — each model's report figures, drawn there
    too by ``figures`` (model name → its return; empty when sampled here)."""
    drawn: dict[str, Any] = {}
    if in_workers(models, jobs):
        tasks = [(campaign, m, priors[m], options, i, figures) for i, m in enumerate(models)]
        done = _here_and_away(tasks)
        drawn = {r.model_name: fig for r, _, fig in done}
        sampled = [(r, said) for r, said, _ in done]
    else:
        sampled = [_recorded(campaign, m, priors[m], options, i) for i, m in enumerate(models)]
    caught = [CaughtWarning(category, message) for _, said in sampled for category, message in said]
    return [r for r, _ in sampled], caught, drawn


def _run(
    campaign: Campaign,
    model: str,
    priors: Any,
    options: SamplingOptions,
    index: int = 0,
    *,
    progress: bool = True,
) -> Any:
    from . import sample_population, sample_posterior  # deferred: arviz

    kw: dict[str, Any] = {
        "seed": model_seed(options.seed, index),
        "progress": progress and options.progress,
        "soil": options.soil,
    }
    if options.draws is not None:
        kw["draws"] = options.draws
    if priors:
        kw["priors"] = priors
    if options.population and has_population(model):
        return sample_population(campaign, model, **kw)
    return sample_posterior(campaign, model, **kw)


def _recorded(
    campaign: Campaign,
    model: str,
    priors: Any,
    options: SamplingOptions,
    index: int,
    *,
    progress: bool = True,
) -> tuple[Any, list[tuple[type[Warning], str]]]:
    """:func:`_run` and the warnings it raised, as (class, text) pairs (a worker's travel
    back as such); the convergence warning every time it is raised."""
    with warnings.catch_warnings(record=True) as recorded:
        warnings.simplefilter("always", ConvergenceWarning)
        result = _run(campaign, model, priors, options, index, progress=progress)
    return result, [(w.category, str(w.message)) for w in recorded]


def _here_and_away(tasks: list[tuple]) -> list[tuple]:
    """:func:`_sample_and_draw` of the first task in this process while the second runs in
    a worker process; the results in the order of ``tasks``."""
    away = in_one_worker(_sample_and_draw, tasks[1])
    here = _sample_and_draw(tasks[0])
    return [here, away.result()]


def _sample_and_draw(task: tuple) -> tuple[Any, list[tuple[type[Warning], str]], Any]:
    """In a worker: one model's posterior (as :func:`_run`), the warnings it raised as
    (class, text), and its report figures (the task's figure function) — drawn where the
    draws are, so only SVG travels back."""
    campaign, model, priors, options, index, figures = task
    result, said = _recorded(campaign, model, priors, options, index, progress=index == 0)
    return result, said, figures(result) if figures is not None else {}
