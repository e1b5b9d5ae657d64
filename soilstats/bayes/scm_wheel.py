"""The Chrono SCM export against the wheel (issue #43 item 8): what a simulator's parameter
sets must not hide about the wheel they will be used for.

* SCM sizes a contact patch l × w as b = l·w/(l + w) (:func:`chrono_contact_width`), not as
  the wheel width w the wheel model uses: where its pressure modulus Kc/b + Kφ differs by
  more than :data:`CONTACT_WIDTH_TOLERANCE` between the two, :func:`contact_width_warning`
  names both (``soilstats posterior --scm-contact LENGTH:WIDTH``, read by
  :func:`contact_patch`);
* a shear posterior over test series of different set-ups (rings, grousers, speeds) is a
  mixture, not the soil under any one wheel: :func:`pooled_series_failure` refuses it,
  :func:`series_refusal` for the shear tests of one soil of a campaign.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..errors import InputError
from ..models import get_model

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign

__all__ = [
    "CONTACT_WIDTH_TOLERANCE",
    "chrono_contact_width",
    "contact_patch",
    "contact_width_warning",
    "pooled_series_failure",
    "series_refusal",
]

#: SCM's modulus at its own contact width may differ from the wheel model's by this share
#: before the export warns (issue #43: a 5.5x softer soil went unsaid).
CONTACT_WIDTH_TOLERANCE = 0.25


def chrono_contact_width(length_m: float, width_m: float) -> float:
    """b [m] SCM takes for an l × w contact patch: l·w/(l + w) (its 1/b = perimeter / (2 area),
    SCMTerrain.cpp:1671)."""
    length_m, width_m = float(length_m), float(width_m)
    if not (np.isfinite(length_m) and np.isfinite(width_m) and length_m > 0 and width_m > 0):
        raise InputError(
            f"the contact patch needs a positive, finite length and width in m, got "
            f"l = {length_m!r}, w = {width_m!r}"
        )
    return length_m * width_m / (length_m + width_m)


def contact_width_warning(
    table: pd.DataFrame, length_m: float, width_m: float, tolerance: float = CONTACT_WIDTH_TOLERANCE
) -> str | None:
    """A warning naming both moduli when SCM's pressure modulus Kc/b + Kphi at its contact
    width b = l·w/(l + w) differs by more than ``tolerance`` from the one at the wheel's width
    w (the b of the Wong–Reece wheel, docs/wheel.md); None when they agree.

    ``table`` is the export's (columns Bekker_Kc, Bekker_Kphi); the medians over its rows are
    compared (each row's own ratio would mix rows whose modulus is near 0).
    """
    b_scm = chrono_contact_width(length_m, width_m)
    kc, kphi = (table[c].to_numpy(float) for c in ("Bekker_Kc", "Bekker_Kphi"))
    at_scm = float(np.median(kc / b_scm + kphi))
    at_wheel = float(np.median(kc / width_m + kphi))
    if at_wheel != 0 and abs(at_scm / at_wheel - 1.0) <= tolerance:
        return None
    ratio = at_scm / at_wheel if at_wheel != 0 else np.inf
    return (
        f"Chrono SCM sizes this {1e3 * length_m:g} x {1e3 * width_m:g} mm contact patch as "
        f"b = l w/(l + w) = {1e3 * b_scm:.3g} mm, where the median pressure modulus Kc/b + Kphi "
        f"is {at_scm:.4g} Pa/m^n, against {at_wheel:.4g} Pa/m^n at the wheel width "
        f"b = {1e3 * width_m:g} mm the wheel model (soilstats wheel) uses: {ratio:.2g} times "
        f"(more than {tolerance:.0%} apart), so SCM's soil is "
        f"{'softer' if abs(at_scm) < abs(at_wheel) else 'stiffer'} than the one validated; "
        "Kc was measured on plates, and SCM extrapolates it to its own width"
    )


def pooled_series_failure(shear_tests: pd.DataFrame) -> str | None:
    """A refusal when the shear tests behind a shear posterior span more than one test series
    (different rings, grousers, speeds: heterogeneous set-ups): its c, φ, K describe their
    mixture, not the soil under any one wheel.  None for one series (or no series column)."""
    if "series" not in shear_tests or shear_tests.empty:
        return None
    series = sorted(str(v) for v in shear_tests["series"].dropna().unique())
    if len(series) < 2:
        return None
    return (
        f"the shear posterior pools {len(series)} test series ({', '.join(series[:6])}) of "
        "different set-ups: its c, phi, K are a mixture, not the soil under any one wheel; "
        "select the series the wheel's shear is like with --select shear:series=NAME"
    )


def contact_patch(text: str | None) -> tuple[float, float] | None:
    """``--scm-contact LENGTH:WIDTH`` in m, checked (None when not given)."""
    if not text:
        return None
    length, _, width = str(text).partition(":")
    try:
        patch = (float(length), float(width))
    except ValueError:
        raise InputError(f"--scm-contact takes LENGTH:WIDTH in metres, got {text!r}") from None
    chrono_contact_width(*patch)  # positive and finite, or an InputError naming both
    return patch


def series_refusal(campaign: Campaign, soil: str, models: Iterable[str]) -> str | None:
    """:func:`pooled_series_failure` of ``soil``'s shear tests when ``models`` has a shear
    model (a shear posterior exported for a simulator must not pool test series of different
    set-ups without --select, docs/posterior.md); None otherwise."""
    if not any(get_model(m).kind == "shear" for m in models):
        return None
    tests = campaign.tests
    return pooled_series_failure(
        tests[(tests["kind"] == "shear") & (tests["soil"].astype(str) == soil)]
    )
