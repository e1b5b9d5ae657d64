"""The priors of one posterior run, read from its ``--prior`` items and ``--priors`` file.

``soilstats posterior`` takes priors as ``NAME=SPEC`` items (``--prior n=0.5:1.5``) and as a
TOML file with one table per model (``--priors FILE``). This module reads them once for the
models of a run: each model gets its table and the items naming its parameters (items win);
a name that belongs to no model is an error before any sampling. With a simulator export,
items naming a parameter the simulator needs that no model identifies (c, phi, K without a
shear model) are user priors (:mod:`soilstats.bayes.stated_priors`), not the models'.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

from ..errors import InputError, ModelError
from ..models import Model, get_model, model_names
from .export import scm_plan
from .priors import check_priors_file, priors_from_items, priors_from_toml
from .stated_priors import parse_stated_prior

__all__ = ["posterior_model", "priors_by_model", "split_prior_items"]


def posterior_model(name: str) -> Model:
    """The record of one model of a posterior run: a registered sinkage or shear model."""
    spec = get_model(name)
    if spec.kind not in ("sinkage", "shear"):
        raise ModelError(
            f"--model {name}: a {spec.kind or 'non-soil'} model has no posterior; choose "
            f"from {model_names('sinkage') + model_names('shear')}"
        )
    return spec


def split_prior_items(
    items: Iterable[str] | None, models: Iterable[str], simulator: str | None = None
) -> tuple[list[str], dict[str, tuple]]:
    """``--prior`` ``items`` for the sampled models' parameters, and user priors: with a
    ``simulator``, items naming a parameter it needs that no model identifies (c, phi, K
    without a shear model), as :mod:`soilstats.bayes.stated_priors` tuples."""
    params = {n for m in models for n in posterior_model(m).param_names}
    unmeasured = set()
    if simulator:
        unmeasured = {k for k, v in scm_plan(params).items() if v == "missing"}
    posterior, stated = [], {}
    for item in items or ():
        name, eq, spec = str(item).partition("=")
        if eq and name.strip() in unmeasured:
            try:
                stated[name.strip()] = parse_stated_prior(spec)
            except ValueError as err:
                raise InputError(f"--prior {item}: {err}") from None
        else:
            posterior.append(item)
    return posterior, stated


def priors_by_model(
    items: Iterable[str] | None,
    priors_file: str | Path | None,
    models: Sequence[str],
    simulator: str | None = None,
) -> dict[str, dict]:
    """Each model's priors, read once: its ``[MODEL]`` table of ``priors_file``, then the
    ``items`` naming its parameters (they win). A name that belongs to no model — or, in the
    file, not to its table's model — is a :class:`ModelError` before any sampling; a table of
    the file naming no registered model is an :class:`InputError` then too
    (:func:`~soilstats.bayes.priors.check_priors_file`). Items that are user priors for the
    ``simulator`` (:func:`split_prior_items`) are not the models'."""
    if priors_file:
        check_priors_file(priors_file)
    raw = split_prior_items(items, models, simulator)[0]
    params = {m: posterior_model(m).param_names for m in models}
    known = {n for names in params.values() for n in names}
    named = {str(item).partition("=")[0].strip() for item in raw if "=" in str(item)}
    unknown = sorted(named - known)
    if unknown:
        hint = (
            ""
            if simulator
            else "; with --simulator chrono-scm, the shear parameters a sinkage-only campaign "
            "lacks take user priors (e.g. --prior c=uniform:0:2000)"
        )
        raise ModelError(
            f"--prior names {unknown}, not parameters of {'+'.join(models)} "
            f"(parameters: {sorted(known)}){hint}"
        )
    parsed = priors_from_items(raw)
    out = {}
    for model, names in params.items():
        table = priors_from_toml(priors_file, model) if priors_file else {}
        stray = sorted(set(table) - set(names))
        if stray:
            raise ModelError(
                f"{priors_file}, [{model}]: {stray} are not parameters of {model} "
                f"(parameters: {list(names)})"
            )
        out[model] = table | {k: v for k, v in parsed.items() if k in names}
    return out
