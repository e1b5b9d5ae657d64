"""The physical gate every kept extension passes, alone or combined.

An extension is *implausible*, and never kept whatever its out-of-sample gain, when

* a parameter it adds lies outside its physical range (side-wall K0 outside 0..1, the
  softening factor f outside 0..1, Reece's frictional k2 < 0 — the health flag
  ``outside-bounds`` of its fit); the base parameters' own red flags (the negative kc of a
  frictional sand, the paper's Table 5) are reported among the red flags instead, or
* it predicts zero or negative pressure (sinkage) or negative shear stress for a test it
  describes (e.g. a per-size trend that drives kc/b + kφ below 0).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from ..fitting.result import FitResult
    from .data import Group
    from .extensions import Fitted

__all__ = ["implausible"]


def _outside_bounds(fit: FitResult, base_fit: FitResult) -> list[str]:
    own = set(fit.param_names) - set(base_fit.param_names)
    return [
        f.message
        for f in fit.flags
        if f.code == "outside-bounds" and f.message.split(" ", 1)[0] in own
    ]


def _non_positive(fitted: Fitted, group: Group, rows: np.ndarray) -> list[str]:
    with np.errstate(all="ignore"):
        y_hat = np.asarray(fitted.extension.predict(fitted, group, rows), float)
    # Sinkage samples all lie at z > 0 (p must be > 0); a shear record starts at j = 0, τ = 0.
    bad = ~(y_hat > 0) if group.kind == "sinkage" else ~(y_hat >= 0)
    if not bad.any():
        return []
    owners = np.unique(group.owner[group.samples_of(rows)][bad])
    return [
        f"predicts non-positive {'pressure' if group.kind == 'sinkage' else 'shear stress'} "
        f"in {owners.size} of {len(rows)} tests"
    ]


def implausible(fitted: Fitted, base_fitted: Fitted, group: Group, rows: ArrayLike) -> list[str]:
    """Why the extension ``fitted`` (on the tests ``rows``) is not physical; empty if it is."""
    return _outside_bounds(fitted.result, base_fitted.result) + _non_positive(
        fitted, group, np.asarray(rows, int)
    )
