"""Least-squares fits asked for twice within one piece of work are made once.

``soilstats posterior`` fits each model before sampling, to refuse what the data cannot
support (:func:`soilstats.bayes.handout.preflight`), and the sampler then starts from the
very same fit (:func:`soilstats.bayes.data.pooled_problem`): on simulated-paper soil01 the
Janosi fit of 130 shear tests cost 0.3 s twice.  Inside ``with reused_fits():``
:func:`~soilstats.identification.fit_sinkage` and :func:`~soilstats.identification.fit_shear`
return the result of an earlier call with the same campaign object, model and arguments.

Only inside the block, and only in the context (thread or task) that opened it: a library
call outside one always fits afresh.  Campaigns are immutable and fit results frozen, so a
reused result is the result a new call would give; calls whose arguments cannot be compared
(an array ``p0``) are never reused.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any, TypeVar

__all__ = ["reusable", "reused_fits"]

F = TypeVar("F", bound=Callable[..., Any])

#: The fits of the open ``reused_fits`` block: key → (campaign, result).  The campaign is
#: held so that its ``id`` (part of the key) cannot be given to another object meanwhile.
_FITS: ContextVar[dict[tuple, tuple[object, object]] | None] = ContextVar(
    "soilstats_reused_fits", default=None
)


@contextmanager
def reused_fits() -> Iterator[None]:
    """Within the block, a fit asked for again with the same arguments is not made again."""
    token = _FITS.set({})
    try:
        yield
    finally:
        _FITS.reset(token)


def frozen_argument(value: object) -> object:
    """A hashable stand-in for an argument: mappings and sequences by content, a model
    record by name and identity; TypeError for what cannot be compared."""
    if isinstance(value, dict):
        return tuple(sorted((k, frozen_argument(v)) for k, v in value.items()))
    if isinstance(value, list | tuple):
        return tuple(frozen_argument(v) for v in value)
    if hasattr(value, "param_names") and hasattr(value, "name"):  # a model record
        return ("model", value.name, id(value))
    hash(value)
    return value


def reusable(fit: F) -> F:
    """Let ``fit(campaign, ...)`` be reused inside :func:`reused_fits` (module docstring)."""
    signature = inspect.signature(fit)

    @functools.wraps(fit)
    def wrapper(campaign: Any, *args: Any, **kwargs: Any) -> Any:
        fits = _FITS.get()
        if fits is None:
            return fit(campaign, *args, **kwargs)
        bound = signature.bind(campaign, *args, **kwargs)
        bound.apply_defaults()
        arguments = {k: v for k, v in bound.arguments.items() if k != "campaign"}
        try:
            key = (fit.__qualname__, id(campaign), frozen_argument(arguments))
        except TypeError:
            return fit(campaign, *args, **kwargs)
        if key not in fits:
            fits[key] = (campaign, fit(campaign, *args, **kwargs))
        return fits[key][1]

    return wrapper  # type: ignore[return-value]
