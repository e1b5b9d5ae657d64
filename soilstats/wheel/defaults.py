"""Defaults that move a verdict (issue #47, item 3): a wheel geometry the user did not give is
tried at its plausible alternative, and a warning is written only where a held-out verdict
changes — so a warning means "this verdict rests on a default", never "a default was used".

The one geometric default with a documented alternative is the shearing radius r_s of a wheel
whose table leaves it out: the default r_s = r (a smooth wheel) against a grousered wheel like
CMU's (63 mm on a 58 mm rim: r_s = 1.1 r; grouser area ratio μ = 0.1 unless given;
docs/wheel.md). Leaving both out of the CMU grousered wheel turns its slip extension's held-out
gain from weak (1.9 SE) to real (2.1 SE).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import replace
from typing import Any

from .geometry import Wheel

__all__ = ["GROUSERED_RS", "grousered", "moved_verdicts"]

#: r_s / r of the grousered alternative (CMU's wheel: 63 / 58 = 1.086, rounded up).
GROUSERED_RS = 1.1
#: Grouser area ratio μ of the grousered alternative where none was given (CMU's wheel).
GROUSERED_MU = 0.1


def grousered(
    wheels: Mapping[str, Wheel], names: Iterable[str], ratio_given: Iterable[str] = ()
) -> dict[str, Wheel]:
    """``wheels`` with each of ``names`` given grousers: r_s = :data:`GROUSERED_RS` · r [m]
    and, unless in ``ratio_given``, μ = :data:`GROUSERED_MU`."""
    chosen, kept = set(names), set(ratio_given)
    out = dict(wheels)
    for name in chosen & set(wheels):
        w = wheels[name]
        mu = w.grouser_area_ratio if name in kept else GROUSERED_MU
        out[name] = replace(w, shear_radius_m=GROUSERED_RS * w.radius_m, grouser_area_ratio=mu)
    return out


def _verdicts(result: Any) -> dict[str, str]:
    """``{gain key: verdict}`` of a :class:`~soilstats.wheel.validation_result.WheelValidation`
    (the held-out gains of its extension; none when the extension was not run)."""
    disc = getattr(result, "discovery", None)
    if disc is None:
        return {}
    return {key: gain.verdict for key, gain in disc.gains.items()}


def moved_verdicts(
    result: Any,
    wheels: Mapping[str, Wheel],
    defaults: Mapping[str, str],
    rerun: Callable[[dict[str, Wheel]], Any],
) -> dict[str, str]:
    """``{"WHEEL: shear_radius_m": warning}`` for the wheels whose shearing radius is among
    ``defaults`` (keys ``"WHEEL: shear_radius_m"``, as the JSON's ``"defaults"``) and whose
    held-out verdicts differ between ``result`` and ``rerun`` with those wheels grousered
    (:func:`grousered`); empty when no verdict moves, and ``rerun`` is not called when no
    shearing radius was defaulted or ``result`` has no held-out gains. A gain pooled over
    wheels (key without ``|WHEEL``) is charged to every defaulted wheel."""
    names = sorted(n for n in wheels if f"{n}: shear_radius_m" in defaults)
    base = _verdicts(result)
    if not names or not base:
        return {}
    given = [n for n in names if f"{n}: grouser_area_ratio" not in defaults]
    alternative = grousered(wheels, names, given)
    other = _verdicts(rerun(alternative))
    out: dict[str, list[str]] = {}
    for key, verdict in base.items():
        new = other.get(key)
        if new is None or new == verdict:
            continue
        scope, _, wheel = key.partition("|")
        for name in [wheel] if wheel else names:
            if name in names:
                out.setdefault(name, []).append(
                    f"the held-out {scope} gain{_of(wheel)} is {verdict}, with grousers {new}"
                )
    return {
        f"{name}: shear_radius_m": (
            f"the shearing radius of {name} moves a verdict: left at r = "
            f"{wheels[name].radius_m:g} m (no grousers) "
            + "; ".join(moved)
            + f" (r_s = {alternative[name].shear_radius_m:.4g} m, μ = "
            f"{alternative[name].grouser_area_ratio:g}); give --shear-radius {name}=RS"
        )
        for name, moved in out.items()
    }


def _of(wheel: str) -> str:
    return f" of {wheel}" if wheel else " (all wheels)"
