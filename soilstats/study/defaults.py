"""Defaults of a study specification that move a verdict (issue #47, item 3).

A sinkage study's pressure response ``log10_p_ref`` is the mean measured pressure within
±``z_window_m`` of the reference sinkage ``z_ref_m``; both are measurement choices with a
default (25 mm, ±1 mm) that a specification may leave out.  For each one left out, the
``log10_p_ref`` effects are tested again at documented alternatives, from the per-test table
already built (the per-test fits are not redone: the pressure is read off the samples), and a
warning is written only where the verdict of an effect (:mod:`.verdict`) differs from the one
at the default — so a warning means "this verdict rests on a default", never "a default was
used".  The alternatives (docs/studies.md, "Defaults that move a verdict"):

* ``z_ref_m``: half and twice the default (12.5 and 50 mm): the pressure–sinkage curve one
  octave shallower and deeper, where the factor's effect on the curve shows as well if it is
  an effect on the soil rather than on one depth.  An alternative is used only where every
  test that reaches the default depth reaches it too (a depth fewer tests reach changes the
  data, not the question);
* ``z_window_m``: halved and doubled (0.5 and 2 mm).

A preparation study's best method (Table 3's criteria, :mod:`.preparation`) is a verdict too:
it is chosen again at each alternative from the per-test table there, and a different choice
is a warning like a moved effect.

Not re-evaluated: ``alpha`` is the user's error-rate policy, not a model of the soil, and
``fallback_model`` feeds only the per-condition parameter tables (no effect verdict reads
them).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import TYPE_CHECKING

import pandas as pd

from ..errors import DefaultWarning
from .result import best_method_name

if TYPE_CHECKING:
    from .spec import StudySpec

__all__ = [
    "BEST_METHOD",
    "RESPONSE",
    "alternatives",
    "moved_verdicts",
    "warn_moved",
    "with_best_method",
]

#: The one response the re-evaluated defaults enter.
RESPONSE = "log10_p_ref"
#: The row :func:`with_best_method` adds: (soil, response) of a preparation study's best method.
BEST_METHOD = ("all soils", "best preparation method")
#: Alternatives as multiples of the default, per spec key.
SCALES = {"z_ref_m": (0.5, 2.0), "z_window_m": (0.5, 2.0)}


def alternatives(spec: StudySpec, defaults: Mapping[str, str]) -> list[tuple[str, float]]:
    """``(key, value)`` of each alternative to try: those of :data:`SCALES` whose key is among
    ``defaults`` (keys ``"spec: KEY"``) of a sinkage study with a ``log10_p_ref`` response."""
    if spec.kind != "sinkage" or RESPONSE not in {r.name for r in spec.responses}:
        return []
    return [
        (key, scale * getattr(spec, key))
        for key, scales in SCALES.items()
        if f"spec: {key}" in defaults
        for scale in scales
    ]


def with_best_method(effects: pd.DataFrame, best: Mapping | None) -> pd.DataFrame:
    """``effects`` with one more row whose verdict is the preparation study's best method
    (``best["best"]``, "none" where no method meets the criteria), so that a default moving
    the choice of method is found as a moved effect verdict is."""
    name = best_method_name(best)
    row = pd.DataFrame([{"soil": BEST_METHOD[0], "response": BEST_METHOD[1], "verdict": name}])
    return row if effects.empty else pd.concat([effects, row], ignore_index=True)


def _verdicts(effects: pd.DataFrame) -> dict[tuple[str, str], str]:
    if effects.empty:
        return {}
    return {
        (str(s), str(r)): str(v)
        for s, r, v in zip(effects["soil"], effects["response"], effects["verdict"], strict=True)
    }


def moved_verdicts(
    spec: StudySpec,
    defaults: Mapping[str, str],
    effects: pd.DataFrame,
    rerun: Callable[[StudySpec], pd.DataFrame | None],
) -> dict[str, str]:
    """``{"spec: KEY": warning}`` for each defaulted key of :func:`alternatives` at which the
    verdict of an effect in ``effects`` (the study's classified table) changes.

    ``rerun(alternative spec)`` returns the classified effects at the
    alternative, or None when the alternative depth is not reached by every test that reaches
    the default (then that alternative is skipped).  Holm adjusts over every response, so a
    changed ``log10_p_ref`` p-value may move another response's verdict too: all are compared.
    """
    base = _verdicts(effects)
    out: dict[str, dict[tuple[str, str], list[str]]] = {}
    for key, value in alternatives(spec, defaults):
        alt = replace(spec, z_ref_m=value) if key == "z_ref_m" else replace(spec, z_window_m=value)
        other = rerun(alt)
        if other is None:
            continue
        for effect, verdict in base.items():
            moved = _verdicts(other).get(effect)
            if moved is not None and moved != verdict:
                out.setdefault(key, {}).setdefault(effect, []).append(f"at {value:g} m '{moved}'")
    return {
        f"spec: {key}": (
            f"the study's {key} moves a verdict: at its default {getattr(spec, key):g} m, "
            + "; ".join(
                f"{soil} {response} is '{base[(soil, response)]}', " + ", ".join(at)
                for (soil, response), at in effects_moved.items()
            )
            + f"; give {key} in the specification"
        )
        for key, effects_moved in out.items()
    }


def warn_moved(moved: Mapping[str, str]) -> None:
    """One :class:`~soilstats.errors.DefaultWarning` per entry of ``moved``."""
    for text in moved.values():
        warnings.warn(text, DefaultWarning, stacklevel=3)
