"""The physical support a simulated soil must respect, read from the model records.

The simulator plants Bekker (kc, kφ, n; Eq. 7) and Janosi (c, φ, K; Eq. 13) parameters.  A
value outside what those models allow (n ≤ 0, kφ ≤ 0, φ ≥ 90°, K ≤ 0, c < 0, a plate modulus
kc/b + kφ ≤ 0) would be simulated without complaint and then refused, or fitted at a bound,
by every analysis downstream: the SPEC is refused instead, naming the key.

The rules come from :attr:`Model.support` (n > 0, c ≥ 0, 0 < φ < 90°, K > 0, kc/b + kφ > 0);
a parameter without a support rule takes its model's finite ``bounds`` (kφ > 0).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ..models import get_model
from .records import SHEAR_PARAMS, SINKAGE_PARAMS

__all__ = ["outside_support"]

#: The model records whose support the simulated parameters must respect.
_MODELS = {"sinkage": "bekker", "shear": "janosi"}


def _rules() -> dict[str, tuple[str, Callable[[float], bool]]]:
    """Parameter -> (what breaking it reads as, test), from the model records."""
    out: dict[str, tuple[str, Callable[[float], bool]]] = {}
    for model in _MODELS.values():
        record = get_model(model)
        for name in record.param_names:
            rule = next((r for r in record.support if getattr(r, "name", None) == name), None)
            if rule is not None:
                out[name] = (f"{rule.label} ({model})", _rule_test(rule, name))
                continue
            lo, hi = record.bounds_of[name]
            if math.isfinite(lo) or math.isfinite(hi):
                out[name] = (f"{name} outside ({lo:g}, {hi:g}) ({model})", _open_range(lo, hi))
    return out


def _rule_test(rule: Any, name: str) -> Callable[[float], bool]:
    return lambda x: bool(rule.holds({name: np.float64(x)}, (1.0, 1.0)))


def _open_range(lo: float, hi: float) -> Callable[[float], bool]:
    return lambda x: lo < x < hi


def outside_support(
    params: dict[str, float], kind: str | None = None, b_m: float | None = None
) -> list[str]:
    """What in ``params`` breaks the models' support: ``["phi = 95 (phi outside (0, 90) deg
    (janosi))"]``, empty when all hold.

    ``kind`` limits the check to the parameters that act on a test of that kind (all given
    ones when None); ``b_m`` (m) adds Bekker's plate modulus kc/b + kφ > 0 at that width.
    """
    rules = _rules()
    names = {"sinkage": SINKAGE_PARAMS, "shear": SHEAR_PARAMS}.get(kind or "", tuple(params))
    bad = [
        f"{k} = {params[k]:g} ({rules[k][0]})"
        for k in names
        if k in params and k in rules and not rules[k][1](params[k])
    ]
    if b_m is not None and kind == "sinkage" and {"kc", "kphi"} <= set(params):
        modulus = params["kc"] / b_m + params["kphi"]
        if not modulus > 0:
            bad.append(f"kc/b + kphi = {modulus:g} at b = {b_m:g} m (must be > 0; bekker)")
    return bad
