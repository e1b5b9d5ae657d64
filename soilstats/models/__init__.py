"""Soil models of the paper, each one record (:class:`Model`) in one registry.

Each record holds the equation with its analytic Jacobian, names, units and plausible bounds,
and everything the layers above ask of the model: kind, data columns, starting values,
priors, physical support, plate sizes needed, population layout, Chrono SCM mapping and
display labels (:mod:`.base`).  :func:`get_model` finds one by name; :func:`register_model`
adds one's own (docs/conventions.md, "The model record").
"""

from __future__ import annotations

from .base import Model
from .registry import (
    MODELS,
    get_model,
    model_names,
    models_of_kind,
    register_built_in,
    register_model,
    unregister_model,
)
from .shear import JANOSI, MOHR_COULOMB, SHEAR_CURVE, side_wall_ratio
from .sinkage import BEKKER, BERNSTEIN, REECE

__all__ = [
    "BEKKER",
    "BERNSTEIN",
    "JANOSI",
    "MODELS",
    "MOHR_COULOMB",
    "REECE",
    "SHEAR_CURVE",
    "Model",
    "get_model",
    "model_names",
    "models_of_kind",
    "register_model",
    "side_wall_ratio",
    "unregister_model",
]

register_built_in(BEKKER, BERNSTEIN, REECE, JANOSI, MOHR_COULOMB, SHEAR_CURVE)
