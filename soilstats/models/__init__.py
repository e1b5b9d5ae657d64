"""Soil models of the paper, each with analytic Jacobian, names, units and plausible bounds."""

from __future__ import annotations

from .base import Model
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
    "side_wall_ratio",
]

MODELS: dict[str, Model] = {
    m.name: m for m in (BEKKER, BERNSTEIN, REECE, JANOSI, MOHR_COULOMB, SHEAR_CURVE)
}


def get_model(name: str | Model) -> Model:
    """The model called ``name`` (or ``name`` itself if it is already a :class:`Model`)."""
    if isinstance(name, Model):
        return name
    try:
        return MODELS[name]
    except KeyError:
        raise ValueError(
            f"unknown model {name!r}; choose one of {sorted(MODELS)} or pass a soilstats.Model"
        ) from None
