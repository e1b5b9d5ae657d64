"""Raw samples of one simulated pressure–sinkage test (Eqs. 6 and 7, Fig. 9).

The plate moves at constant velocity from ``start_m`` (slightly above the surface, so the
first readings are the sensor's zero: small, often negative forces) to ``sinkage_m``; the
samples are equally spaced in time, hence in z.  The true pressure is Bekker's (Eq. 7) with
the test's drawn parameters, reduced beyond z_c for narrow plates where a softening effect is
planted; the recorded force is p·A (Eq. 6) plus a per-test zero offset and white noise.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..models import BEKKER
from .effects import soften
from .records import Noise, Resolution

__all__ = ["quantise", "sinkage_samples"]


def quantise(values: np.ndarray, step: float) -> np.ndarray:
    """Round to a multiple of ``step``, then to the step's decimals so CSV text stays short."""
    if step <= 0:
        return values
    decimals = max(0, int(np.ceil(-np.log10(step))) + 1)
    return np.round(np.round(values / step) * step, decimals) + 0.0  # + 0.0 drops −0.0


def sinkage_samples(
    row: dict[str, Any],
    params: dict[str, float],
    softening: tuple[float, float] | None,
    noise: Noise,
    resolution: Resolution,
    start_m: float,
    sinkage_m: float,
    points: int,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, float]:
    """(z [m], force [N], zero offset [N]) of one test, z and force quantised.

    Parameters
    ----------
    row : dict
        The test's row (``b_m`` [m] and ``area_m2`` [m²] are used).
    params : dict
        The test's drawn ``kc`` [N/m^(n+1)], ``kphi`` [N/m^(n+2)], ``n`` [-].
    softening : (z_c [m], factor) or None
        Fig. 9's second stage, from :func:`soilstats.simulation.effects.softening_of`.
    noise, resolution
        From the SPEC.
    start_m, sinkage_m : float
        First and last plate position [m]; z ≤ 0 is above the surface (p = 0).
    points : int
        Number of samples.
    rng : numpy.random.Generator
        Noise stream; ``1 + 2·points`` normals are drawn whatever the noise levels.
    """
    z = quantise(np.linspace(start_m, sinkage_m, points), resolution.z_m)
    theta = (params["kc"], params["kphi"], params["n"])
    x = np.vstack([np.full(points, row["b_m"]), z])
    p = BEKKER.func(x, *theta)
    if softening is not None:
        zc, factor = softening
        p_zc = float(BEKKER.func(np.array([[row["b_m"]], [zc]]), *theta)[0])
        p = soften(z, p, p_zc, zc, factor)
    offset = noise.force_offset_N * rng.standard_normal()
    rel = rng.standard_normal(points)
    white = rng.standard_normal(points)
    force = p * row["area_m2"] * (1.0 + noise.force_rel * rel) + offset + noise.force_N * white
    return z, quantise(force, resolution.force_N), offset
