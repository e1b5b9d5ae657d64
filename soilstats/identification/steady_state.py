"""The steady-state rule for shear tests (Section 2.2, before Eq. 15).

The paper fits Mohr–Coulomb "from measurement data of the steady-state part", the part after
which "there is no change in shear stress even if the shear motion continues".  We make that
operational and testable:

1. The plateau level τ_ss is the median shear stress over the last ``tail`` fraction (25 %) of
   the record's shear deformation j.
2. The steady-state part starts at the first sample from which a running median of τ
   (window: 2 % of the samples, at least 5) stays at or above ``level`` (98 %) of τ_ss — or,
   where the record is noisier than that band, above τ_ss minus three standard deviations of
   the running median (noise measured robustly, by the MAD, on the tail).  Without the noise
   allowance a record with ~1 % noise never "stays" above 98 % and is wrongly rejected.
3. The part must be steady: a straight line fitted to τ(j) over it may change by at most
   ``max_drift`` (10 %) of τ_ss across the part, and the part must hold at least
   ``min_samples`` (10) samples.  Otherwise the test is reported as not reaching a steady
   state — it is not silently used.

For a Janosi–Hanamoto curve τ = τ_max(1 − e^(−j/K)), step 2 gives j_ss ≈ K·ln 50 ≈ 3.9K.
The part still holds the last ≤ 2 % of the rise, so Mohr–Coulomb on it reads τ_max low by
the part's mean shortfall — about 0.5 % for records that run to ~8K (a 95 % level would
double that).  Records much shorter than 4K never pass step 3 and are reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import median_filter

__all__ = ["SteadyState", "steady_state"]


@dataclass(frozen=True)
class SteadyState:
    start: int  # first index (in j-sorted order) of the steady part
    indices: np.ndarray  # indices into the original record of the steady samples
    tau_level: float  # τ_ss, Pa
    drift: float  # relative change of the fitted line across the part
    steady: bool
    reason: str


def steady_state(
    j: np.ndarray,
    tau: np.ndarray,
    *,
    tail: float = 0.25,
    level: float = 0.98,
    max_drift: float = 0.10,
    min_samples: int = 10,
) -> SteadyState:
    """Locate the steady-state part of one shear record (see the module docstring)."""
    j = np.asarray(j, float)
    tau = np.asarray(tau, float)
    order = np.argsort(j, kind="stable")
    js, ts = j[order], tau[order]
    span = js[-1] - js[0]
    tail_mask = js >= js[-1] - tail * span
    tau_level = float(np.median(ts[tail_mask]))
    window = max(5, int(0.02 * ts.size) | 1)
    # Mirrored at the ends: padded with copies of the edge sample ("nearest"), the window at
    # the last sample is mostly that sample, so one low final reading put the start past the
    # end and rejected the test (2 of 260 clean bundled shear tests).
    smooth = median_filter(ts, size=window, mode="mirror")
    tail_noise = 1.4826 * np.median(np.abs(ts[tail_mask] - smooth[tail_mask]))
    # The running median of `window` samples scatters by ≈ 1.25·sd/√window.
    allowance = max((1.0 - level) * abs(tau_level), 3.0 * 1.25 * tail_noise / np.sqrt(window))
    below = np.flatnonzero(smooth < tau_level - allowance)
    start = int(below[-1] + 1) if below.size else 0
    part = order[start:]
    if part.size < min_samples:
        return SteadyState(
            start,
            part,
            tau_level,
            np.nan,
            False,
            f"only {part.size} samples after τ reaches {level:.0%} of its plateau",
        )
    jp, tp = js[start:], ts[start:]
    if jp[-1] > jp[0]:
        slope = np.polyfit(jp, tp, 1)[0]
        drift = float(abs(slope) * (jp[-1] - jp[0]) / abs(tau_level)) if tau_level else np.inf
    else:
        drift = 0.0
    steady = drift <= max_drift
    reason = (
        f"steady from j = {jp[0]:.4g} m ({part.size} samples), drift {drift:.1%}"
        if steady
        else f"τ still drifts by {drift:.1%} (> {max_drift:.0%}) over the last part"
    )
    return SteadyState(start, part, tau_level, drift, steady, reason)
