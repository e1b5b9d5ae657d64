"""Physical support of parameter draws: what a rover Monte Carlo may be handed.

A draw is physical when every value is finite and

* n > 0 (sinkage grows with depth; Eq. 7, Eq. 8);
* the plate modulus is positive over the contact widths the draws will be used at: Bekker
  kc/b + kφ > 0, Reece k1 + k2·b > 0, Bernstein k > 0, for every b in [b_min, b_max] (both
  moduli are monotone in b, so the two ends decide);
* c >= 0, 0 < φ < 90°, K > 0 (shear, Eqs. 13, 15).

These are the rules of each model's record (``Model.support``, :mod:`soilstats.models`).

The pooled posterior already has this support through its priors (at the tested plate
sizes); a population's *new preparation* is drawn from a fitted scatter distribution and can
leave it, and a posterior that is not proper (data that do not pin the parameters) can wander
to any value. Draws outside are never written: the kept draws are the posterior conditioned on
physics (rejection), and the share left out is a diagnostic — above :data:`MAX_OUTSIDE` the
model does not describe the soil and the CLI writes nothing unless forced.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..errors import InputError
from ..models import MODELS, get_model

if TYPE_CHECKING:
    from ..models.base import Model

__all__ = [
    "MAX_OUTSIDE",
    "SupportCheck",
    "check_support",
    "negative_modulus_width",
    "widths_text",
]

#: Largest share of draws outside the physical support for a posterior to be usable.
MAX_OUTSIDE = 0.01


@dataclass(frozen=True)
class SupportCheck:
    """Which draws are physical, and why the others are not.

    Attributes
    ----------
    inside : ndarray of bool
        One entry per draw.
    reasons : dict
        Rule -> number of draws breaking it (a draw can break several).
    contact_widths : tuple of float
        (b_min, b_max) [m] the moduli were checked over.
    """

    inside: np.ndarray
    reasons: dict
    contact_widths: tuple[float, float]

    @property
    def n_outside(self) -> int:
        return int((~self.inside).sum())

    @property
    def share_outside(self) -> float:
        return self.n_outside / max(len(self.inside), 1)

    @property
    def passed(self) -> bool:
        return self.share_outside <= MAX_OUTSIDE

    def describe(self) -> str:
        widths = widths_text(*self.contact_widths)
        if not self.n_outside:
            return f"all {len(self.inside)} draws physical ({widths})"
        why = ", ".join(f"{rule}: {count}" for rule, count in self.reasons.items() if count)
        return (
            f"{self.n_outside} of {len(self.inside)} draws ({self.share_outside:.1%}) outside "
            f"the physical support at {widths} ({why})"
        )

    def to_dict(self) -> dict:
        return {
            "draws": len(self.inside),
            "outside": self.n_outside,
            "share_outside": self.share_outside,
            "max_share": MAX_OUTSIDE,
            "passed": self.passed,
            "reasons": {k: int(v) for k, v in self.reasons.items()},
            "contact_widths_m": list(self.contact_widths),
        }


def widths_text(lo: float, hi: float) -> str:
    """``"contact widths 0.025–0.075 m"``, or ``"contact width 0.0757 m"`` for one plate
    size (not a range from a value to itself)."""
    if lo == hi:
        return f"contact width {lo:.3g} m"
    return f"contact widths {lo:g}–{hi:g} m"


def check_support(
    draws: pd.DataFrame,
    contact_widths: tuple[float, float],
    models: Iterable[str | Model] | None = None,
) -> SupportCheck:
    """Judge each row of ``draws`` (columns named as the models' parameters, φ in degrees).

    ``contact_widths``: (b_min, b_max) [m], the plate or wheel contact widths of the draws' use.
    ``models``: the models (names or records) whose support rules apply (``Model.support``,
    judged in the order of registration); by default every registered model's.  A rule
    applies where its parameters are columns of ``draws``; one that several models share
    (c ≥ 0) is judged once.
    """
    lo, hi = (float(b) for b in contact_widths)
    if not 0 < lo <= hi:
        raise InputError(f"contact widths must satisfy 0 < b_min <= b_max, got {contact_widths}")
    values = {c: draws[c].to_numpy(float) for c in draws.columns}
    if models is None:
        chosen = list(MODELS.values())
    else:  # in the registry's order, as by default: the reasons read the same either way
        order = list(MODELS.values())
        chosen = sorted(
            (get_model(m) for m in models),
            key=lambda m: order.index(m) if m in order else len(order),
        )
    rules = {"non-finite": ~np.all(np.isfinite(draws.to_numpy(float)), axis=1)}
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        for model in chosen:
            for rule in model.support:
                if rule.label not in rules and set(rule.params) <= set(values):
                    rules[rule.label] = ~rule.holds(values, (lo, hi))
    outside = np.zeros(len(draws), bool)
    for broken in rules.values():
        outside |= broken
    return SupportCheck(~outside, {k: int(v.sum()) for k, v in rules.items()}, (lo, hi))


def negative_modulus_width(draws: pd.DataFrame, quantile: float = 0.99) -> float | None:
    """The contact width [m] below which Bekker's modulus kc/b + kφ turns negative.

    A draw with kc < 0 (and kφ > 0) has a negative modulus for b < −kc/kφ; a draw with
    kc >= 0 never does (width 0). Returns the ``quantile`` of that width over all draws: at
    contact widths above it, all but 1 − ``quantile`` of the draws give a positive modulus.
    None when no draw has kc < 0.
    """
    if not {"kc", "kphi"} <= set(draws.columns):
        return None
    kc, kphi = draws["kc"].to_numpy(float), draws["kphi"].to_numpy(float)
    negative = (kc < 0) & (kphi > 0)
    if not negative.any():
        return None
    width = np.zeros(kc.size)
    width[negative] = -kc[negative] / kphi[negative]
    return float(np.quantile(width, quantile))
