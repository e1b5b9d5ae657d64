"""The registry of soil models: one record per model, asked by name by every layer.

>>> from soilstats.models import get_model, models_of_kind
>>> get_model("bekker").min_plate_sizes
2
>>> [m.name for m in models_of_kind("sinkage")]
['bekker', 'bernstein', 'reece']

A model of one's own is one :class:`~soilstats.models.Model` and one call,
``register_model(MY_MODEL)``; from then on ``fit_sinkage(campaign, "my-model")``, the
posteriors, discovery and the studies take it by name (docs/conventions.md, "The model
record").  An unknown name is a :class:`~soilstats.errors.ModelError` that lists the known
ones, never a silent default.
"""

from __future__ import annotations

from ..errors import ModelError
from .base import KINDS, Model

__all__ = [
    "MODELS",
    "get_model",
    "model_names",
    "models_of_kind",
    "register_model",
    "unregister_model",
]

#: Every registered model by name, in the order of registration (the paper's first).
MODELS: dict[str, Model] = {}


def register_model(model: Model, *, replace: bool = False) -> Model:
    """Register ``model`` under its name; returns it (so a module can write
    ``MY_MODEL = register_model(Model(...))``).

    The record must state its ``kind`` (:data:`~soilstats.models.base.KINDS`) and the data
    ``columns`` its ``x`` is made of; a name already taken is an error unless ``replace``
    (and the paper's models cannot be replaced).
    """
    if not isinstance(model, Model):
        raise ModelError(f"register_model takes a soilstats.Model, got {type(model).__name__}")
    if model.kind not in KINDS:
        raise ModelError(f"model {model.name!r}: kind must be one of {KINDS}, got {model.kind!r}")
    if not model.columns:
        raise ModelError(f"model {model.name!r} names no data columns (Model.columns)")
    taken = MODELS.get(model.name)
    if taken is not None and taken is not model:
        if not replace or model.name in _BUILT_IN:
            raise ModelError(
                f"a model called {model.name!r} is registered already"
                + ("" if model.name in _BUILT_IN else "; pass replace=True to replace it")
            )
    MODELS[model.name] = model
    return model


def unregister_model(name: str) -> None:
    """Remove a registered model of one's own (the paper's models stay)."""
    if name in _BUILT_IN:
        raise ModelError(f"{name!r} is one of the paper's models and stays registered")
    MODELS.pop(name, None)


def get_model(name: str | Model, kind: str | None = None) -> Model:
    """The model called ``name`` (or ``name`` itself if it is already a :class:`Model`).

    ``kind``: the kind the caller fits (``"sinkage"``, ``"shear"``); a model of another
    kind is an error naming the models of that kind.

    Raises
    ------
    ModelError
        An unknown name (the message lists the registered models), or the wrong kind.
    """
    if isinstance(name, Model):
        model = name
    else:
        found = MODELS.get(name)
        if found is None:
            known = model_names(kind)
            raise ModelError(
                f"unknown model {name!r}; choose one of {known} "
                "(or register your own: soilstats.register_model)"
            )
        model = found
    if kind is not None and model.kind != kind:
        raise ModelError(
            f"{model.name!r} is a {model.kind or 'non-soil'} model; for {kind} tests choose one "
            f"of {model_names(kind)}"
        )
    return model


def models_of_kind(kind: str) -> tuple[Model, ...]:
    """The registered models of one kind, in the order of registration."""
    if kind not in KINDS:
        raise ModelError(f"unknown kind {kind!r}; the kinds are {KINDS}")
    return tuple(m for m in MODELS.values() if m.kind == kind)


def model_names(kind: str | None = None) -> list[str]:
    """Names of the registered models (of one kind), in the order of registration."""
    models = MODELS.values() if kind is None else models_of_kind(kind)
    return [m.name for m in models]


_BUILT_IN: frozenset[str] = frozenset()


def register_built_in(*models: Model) -> None:
    """Register the paper's built-in ``models``: never replaced, never unregistered.

    Called once, by :mod:`soilstats.models` at import (public so that the package can; a
    user's own model goes through :func:`register_model`)."""
    global _BUILT_IN
    for model in models:
        register_model(model)
    _BUILT_IN = _BUILT_IN | {m.name for m in models}
