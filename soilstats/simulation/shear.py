"""Raw samples of one simulated shear-ring test (Eqs. 12–14, side walls of the grousers).

The ring turns at constant rate through the angle that gives shear deformation
``shear_deformation_m`` at the mean radius (Eq. 14).  The controller holds the normal force
near its set point σ·A_ring; its wobble (controller noise) moves the true σ, and the sensor
records it with noise.  The shear stress under the ring follows Janosi–Hanamoto (Eq. 13,
exponent −j/K) with the test's drawn c, φ, K; the torque is that stress through Eq. 12
inverted, plus — where a side-wall effect is planted — the shear on the inner and outer
cylindrical walls of height h, plus a per-test zero offset and white noise.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..campaign.derived import ring_area, ring_torque
from .records import Noise, Resolution
from .sinkage import quantise

__all__ = ["shear_samples"]


def shear_samples(
    row: dict[str, Any],
    params: dict[str, float],
    K0: float | None,
    noise: Noise,
    resolution: Resolution,
    shear_deformation_m: float,
    points: int,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(angle [rad], torque [N·m], normal force [N], torque zero offset [N·m]) of one test.

    Parameters
    ----------
    row : dict
        ``r_inner_m``, ``r_outer_m``, ``grouser_height_m`` [m] and the set point
        ``normal_pressure_Pa`` [Pa].
    params : dict
        The test's drawn ``c`` [Pa], ``phi`` [deg], ``K`` [m].
    K0 : float or None
        Lateral stress coefficient of the side walls (None: no side-wall shear).
    noise, resolution
        From the SPEC.
    shear_deformation_m : float
        j at the end of the test [m].
    points : int
        Number of samples.
    rng : numpy.random.Generator
        Noise stream; ``1 + 3·points`` normals are drawn whatever the noise levels.
    """
    ri, ro, h = row["r_inner_m"], row["r_outer_m"], row["grouser_height_m"]
    r_mean = 0.5 * (ri + ro)
    angle = quantise(np.linspace(0.0, shear_deformation_m / r_mean, points), resolution.angle_rad)
    j = r_mean * angle  # Eq. 14
    offset = noise.torque_offset_Nm * rng.standard_normal()
    wobble = rng.standard_normal(points)
    sensor = rng.standard_normal(points)
    white = rng.standard_normal(points)
    sigma = row["normal_pressure_Pa"] * (1.0 + noise.normal_force_rel * wobble)
    tan_phi = np.tan(np.radians(params["phi"]))
    growth = -np.expm1(-j / params["K"])
    tau = (params["c"] + sigma * tan_phi) * growth  # Eq. 13
    torque = ring_torque(tau, ri, ro)  # Eq. 12 inverted
    if K0 is not None and h > 0:
        wall_stress = (params["c"] + K0 * sigma * tan_phi) * growth
        torque = torque + 2.0 * np.pi * h * (ri**2 + ro**2) * wall_stress
    torque = torque + offset + noise.torque_Nm * white
    normal_force = sigma * ring_area(ri, ro) + noise.normal_force_N * sensor
    return (
        angle,
        quantise(torque, resolution.torque_Nm),
        quantise(normal_force, resolution.normal_force_N),
        offset,
    )
